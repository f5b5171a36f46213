"""Colour plans: format version 2, thread colours, the joint planner, render and score, G-code pauses."""

import json

import numpy as np
import pytest
from PIL import Image

from firmware_protocol.machine import load_machine
from firmware_protocol.world import World
from bundled import GCODE_MACHINES
from gcode_replay import replay
from stringbot.cli import main
from stringbot.errors import BadInput
from stringbot.motion import gcode_job, hook_steps
from stringbot.motion.layers import layer_estimates
from stringbot.planner import Plan, read_plan, write_plan
from stringbot.planner.colour.build import plan_colour
from stringbot.planner.colour.render import colour_score, plan_layers
from stringbot.planner.picture.read import read_picture
from stringbot.planner.colour.palette import parse_background, parse_color, parse_colors, threads
from stringbot.planner.colour.reach import auto_palette
from stringbot.planner.model.thread import ThreadModel


def ring_xy(pins):
    a = np.arange(pins) * 2 * np.pi / pins
    return np.stack([0.5 + 0.5 * np.sin(a), 0.5 - 0.5 * np.cos(a)], axis=1)


def colour_plan(pins=300, layers=None, seed=2, n=(7, 6, 5)):
    """A hand-made 3-layer plan (layers of random pins)."""
    rng = np.random.default_rng(seed)
    if layers is None:
        layers = []
        for color, k in zip(("#1f5bb5", "#c8102e", "#141414"), n):
            seq = [int(rng.integers(pins))]
            while len(seq) < k:
                p = int(rng.integers(pins))
                if p != seq[-1]:
                    seq.append(p)
            layers.append((color, seq))
    return Plan.from_layers(layers, background="#ffffff", pins=pins, frame="circle", pin_xy=ring_xy(pins),
                            crop={"cx": 50, "cy": 50, "r": 50}, method="hand", parameters={},
                            stats={"lines": 0}, source={"path": "x.png", "sha256": "0" * 64, "width": 100,
                                                        "height": 100})


def run(argv, capsys):
    with pytest.raises(SystemExit) as info:
        main(argv)
    out, err = capsys.readouterr()
    return info.value.code, out, err


@pytest.fixture
def picture(tmp_path):
    """A small colour picture: a red upper half, a blue lower half, a black bar across the middle."""
    n = 64
    img = np.full((n, n, 3), 255, np.uint8)
    img[:32] = (200, 16, 46)
    img[32:] = (31, 91, 181)
    img[28:36, 16:48] = (20, 20, 20)
    path = tmp_path / "pic.png"
    Image.fromarray(img).save(path)
    return path


#: A small ring and a thick thread: a few hundred chords cover a 60-pin picture as thousands cover a 300-pin one.
THICK = ThreadModel(diameter_mm=100, thread_mm=0.5)


# ---- the plan file ----------------------------------------------------------------------------------

def test_version_2_round_trip(tmp_path):
    plan = colour_plan()
    path = tmp_path / "c.json"
    write_plan(plan, path)
    doc = json.loads(path.read_text())
    assert doc["version"] == 2 and "sequence" not in doc and doc["background"] == "#ffffff"
    assert [lay["color"] for lay in doc["layers"]] == ["#1f5bb5", "#c8102e", "#141414"]
    back = read_plan(path)
    assert back.colors == plan.colors and back.layer_starts == [0, 7, 13]
    assert back.sequence == plan.sequence and len(back.sequence) == 18
    assert back.chord_list() == plan.chord_list() and len(back.chord_list()) == 6 + 5 + 4  # no chord across layers
    assert back.sha256() == plan.sha256()
    assert [lay.sequence for lay in back.layers] == [lay.sequence for lay in plan.layers]


def test_mono_plans_stay_version_1_and_a_v2_mono_plan_is_one_layer(tmp_path):
    mono = colour_plan(layers=[("#000000", [0, 100, 200, 50])])
    assert mono.is_mono and json.loads(mono.to_json())["version"] == 1
    assert mono.layers[0].sequence == [0, 100, 200, 50]
    white_on_black = colour_plan(layers=[("#f4f4f0", [0, 100, 200, 50])])
    white_on_black.background = "#000000"
    path = tmp_path / "w.json"
    write_plan(white_on_black, path)
    back = read_plan(path)
    assert json.loads(path.read_text())["version"] == 2
    assert back.sequence == [0, 100, 200, 50] and back.colors == ["#f4f4f0"] and back.background == "#000000"
    assert back.sha256() != mono.sha256()      # the thread's colour is part of what is wound


@pytest.mark.parametrize("change, words", [
    (lambda d: d.pop("layers"), "missing field 'layers'"),
    (lambda d: d.update(layers=[]), "'layers' is empty"),
    (lambda d: d["layers"][1].update(color="red"), "layers[1].color"),
    (lambda d: d["layers"][0].update(sequence=[3]), "layers[0].field 'sequence' has 1 pins"),
    (lambda d: d["layers"][2]["sequence"].append(999), "layers[2].sequence[5]"),
    (lambda d: d.update(background="white"), "'background'"),
    (lambda d: d.update(version=3), "version 3"),
])
def test_version_2_contract_violations_name_the_field(tmp_path, change, words):
    doc = json.loads(colour_plan().to_json())
    change(doc)
    path = tmp_path / "c.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(BadInput) as info:
        read_plan(path)
    assert words in str(info.value)


# ---- colours ------------------------------------------------------------------------------------

def test_colour_names_and_hex():
    assert parse_color("#B22222") == "#b22222" and parse_color("#fff") == "#ffffff"
    assert parse_color("Dark Green") == threads()["dark-green"] == parse_color("dark_green")
    assert parse_background("white") == "#ffffff" and parse_background("black") == "#000000"
    assert parse_colors("black, crimson ,#1f5bb5") == [threads()["black"], "#b22222", "#1f5bb5"]
    assert parse_colors("auto:3") == ("auto", 3)
    # the British spelling names the same threads
    assert parse_color("grey") == threads()["gray"] and parse_color("Dark Grey") == threads()["dark-gray"]
    assert parse_color("light_grey") == threads()["light-gray"]


@pytest.mark.parametrize("text, background, words", [
    ("black,mauve", "#ffffff", "unknown colour 'mauve'"),
    ("#12345g", "#ffffff", "not a colour"),
    ("#1234", "#ffffff", "not a colour"),
    ("auto:0", "#ffffff", "auto:N with N in 1..8"),
    ("auto:99", "#ffffff", "auto:N with N in 1..8"),
    ("auto:x", "#ffffff", "auto:N"),
    ("black,black", "#ffffff", "twice"),
    ("black,white", "#ffffff", "colour of the board"),
    ("red,#000000", "#000000", "colour of the board"),
    (",", "#ffffff", "names no colour"),
    ("red,,blue", "#ffffff", "empty item"),
    ("red,", "#ffffff", "empty item"),
])
def test_bad_colours(text, background, words):
    with pytest.raises(BadInput) as info:
        parse_colors(text, background=background)
    assert words in str(info.value)


@pytest.mark.parametrize("args, words", [
    (["--colors", "black,mauve"], "unknown colour 'mauve'"),
    (["--colors", "auto:0"], "auto:N with N in 1..8"),
    (["--colors", "auto:99"], "auto:N with N in 1..8"),
    (["--colors", "#zzzzzz"], "not a colour"),
    (["--colors", "red,,blue"], "has an empty item"),
    (["--colors", "black,red", "--background", "black"], "colour of the board"),
    (["--background", "#12"], "not a colour"),
    (["--colors", "black", "--style", "fill"], "--style is a knob of the one-thread planner"),
    (["--colors", "black,red", "--spool-changes", "-1"], "--spool-changes -1; expected 0..500"),
    (["--colors", "black,red", "--min-run", "0"], "--min-run 0; expected a number of lines >= 1"),
    (["--spool-changes", "3"], "--spool-changes is a knob of the colour planner; give --colors too"),
    (["--colors", "auto:4:black,red"], "4 threads among 2"),
])
def test_cli_bad_colour_input_is_one_line_exit_2_and_writes_nothing(tmp_path, picture, capsys, args, words):
    out = tmp_path / "p.json"
    code, _, err = run(["plan", str(picture), "-o", str(out), "--pins", "40", "--size", "64"] + args, capsys)
    assert code == 2 and words in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists() and not (tmp_path / "p.png").exists()


def test_auto_palette_finds_the_picture_s_threads(picture):
    pic = read_picture(picture, size=64)
    names = {v: k for k, v in threads().items()}
    got = [names[c] for c in auto_palette(pic.rgb, 3).colors]
    assert len(set(got)) == 3
    assert "black" in got or "dark-gray" in got
    assert any(n in got for n in ("red", "crimson", "burgundy")) and any(n in got for n in ("blue", "navy"))


# ---- the planner, render, score --------------------------------------------------------------------

def test_joint_planner_beats_black_only_at_the_same_line_count(picture):
    colours = plan_colour(picture, colors=["#141414", "#c8102e", "#1f5bb5"], pins=60, size=64, lines=800,
                          cache=False, model=THICK, spool_changes=4, min_run=60)
    k = colours.stats["lines"]
    assert 400 <= k <= 800 and 3 <= len(colours.colors) <= 5 and set(colours.colors) == {"#141414", "#c8102e",
                                                                                         "#1f5bb5"}
    assert all(len(lay.sequence) - 1 >= 60 for lay in colours.layers[:-1])
    assert all(a.color != b.color for a, b in zip(colours.layers[:-1], colours.layers[1:]))
    black = plan_colour(picture, colors=["#141414"], pins=60, size=64, lines=k, cache=False, model=THICK)
    ref = read_picture(picture, size=512, crop=colours.crop).rgb
    c = colour_score(plan_layers(colours), colours.pin_xy, ref, frame="circle", thread_fraction=THICK.fraction)
    b = colour_score(plan_layers(black), black.pin_xy, ref, frame="circle", thread_fraction=THICK.fraction)
    assert black.stats["lines"] <= k
    assert c["delta_e"] < b["delta_e"] / 2, (c, b)
    assert colours.stats["model_error"] < colours.stats["model_error_start"] / 3


def test_plan_render_score_through_the_cli(tmp_path, picture, capsys):
    out = tmp_path / "c.json"
    code, text, err = run(["plan", str(picture), "-o", str(out), "--pins", "60", "--size", "64", "--lines", "200",
                           "--colors", "black,crimson,blue", "--no-cache"], capsys)
    assert code == 0, err
    assert "colour: 60 pins" in text and "spool change" in text
    plan = read_plan(out)
    metres = plan.stats["thread_diameters"] * 500 / 1000.0          # on the default 500 mm frame, as a mono plan
    assert f"thread {metres:.1f} m," in text
    assert plan.version == 2 and plan.method == "colour" and 3 <= len(plan.colors) <= 9 and len(set(plan.colors)) == 3
    preview = np.asarray(Image.open(tmp_path / "c.png"))
    assert preview.shape == (1001, 1001, 3)
    red = (preview[..., 0].astype(int) - preview[..., 2]) > 40
    assert red.any()                                             # drawn in colour, as woven
    code, text, err = run(["render", str(out), "-o", str(tmp_path / "r.png"), "--size", "300"], capsys)
    assert code == 0 and np.asarray(Image.open(tmp_path / "r.png")).shape == (300, 300, 3)
    code, text, err = run(["score", str(out), "--json"], capsys)
    assert code == 0, err
    r = json.loads(text)
    assert 0 < r["delta_e"] < 60 and -1 <= r["ssim"] <= 1 and r["colors"] == plan.colors


# ---- estimates and G-code --------------------------------------------------------------------------

def test_estimates_per_layer_add_up():
    plan, machine = colour_plan(), load_machine("grbl-ring")
    from stringbot.motion import estimate
    est = estimate(plan, machine)
    per = layer_estimates(plan, machine)
    assert [le.steps for le in per] == [7, 6, 5] and [le.first_step for le in per] == [0, 7, 13]
    assert abs(sum(le.thread_m for le in per) - est.thread_m) < 1e-9
    assert abs(sum(le.seconds for le in per) - est.seconds) < 1e-6
    assert [le.tie_on_pin for le in per] == [lay.sequence[0] for lay in plan.layers]


@pytest.mark.parametrize("name", GCODE_MACHINES)
def test_gcode_pauses_at_each_spool_change(name):
    plan, machine = colour_plan(), load_machine(name)
    text = gcode_job(plan, machine, plan_name="c.json")
    lines = text.splitlines()
    pauses = [i for i, line in enumerate(lines) if line == "M0"]
    assert len(pauses) == 2
    for k, i in enumerate(pauses, 1):
        lay = plan.layers[k]
        comment = next(line for line in reversed(lines[:i]) if line.startswith("; spool change"))
        assert f"spool change {k} of 2" in comment and lay.color in comment
        assert f"at pin {lay.sequence[0]}" in comment and f"tie it off at pin {plan.layers[k - 1].sequence[-1]}" in comment
        nxt = next(line for line in lines[i + 1:] if line.startswith("; pin"))
        assert nxt.startswith(f"; pin {lay.sequence[0]} (step {plan.layer_starts[k] + 1}/")
        if name == "marlin-ring":
            assert lines[i - 1] == f"M117 Tie {'red' if k == 1 else 'black'} on pin {lay.sequence[0]}"
            assert lines[i - 2] == "M400"
    assert "; tie the blue (#1f5bb5) thread on at pin" in text


def test_gcode_of_a_colour_plan_winds_every_layer_when_the_operator_ties_on_at_each_pause():
    """Replay the program on the world, the operator tying each layer's thread on at its pause."""
    plan, machine = colour_plan(), load_machine("grbl-ring")
    text = gcode_job(plan, machine)
    pieces = text.split("\nM0\n")
    assert len(pieces) == 3
    world = World(machine)
    for color, piece in zip(plan.colors, pieces):
        world.tie_on(color)
        replay(piece, machine, world=world)
    assert world.collisions == []
    assert [(w.pin, w.color) for w in world.wraps] == [(p, lay.color) for lay in plan.layers for p in lay.sequence]
    steps = hook_steps(plan, machine)
    assert [w.direction for w in world.wraps] == [s.direction for s in steps]


def test_animate_draws_each_layer_in_its_colour_a_later_one_on_top(tmp_path, capsys):
    from PIL import Image
    path, gif = tmp_path / "c.json", tmp_path / "a.gif"
    # pins 0 (top) -> 150 (bottom): red, vertical; then 75 (right) -> 225 (left) -> 0: blue, across it
    plan = colour_plan(layers=[("#c8102e", [0, 150]), ("#1f5bb5", [75, 225, 0])])
    plan.diameter_mm, plan.thread_mm = 100.0, 1.0          # a thread 10 px wide: its middle covers whole pixels
    write_plan(plan, path)
    code, _, err = run(["animate", str(path), "-o", str(gif), "--frames", "3", "--size", "1001"], capsys)
    assert code == 0, err
    im = Image.open(gif)
    frames = []
    for k in range(im.n_frames):
        im.seek(k)
        frames.append(np.asarray(im.convert("RGB")).astype(int))
    assert len(frames) == 3
    red, blue = (0xc8, 0x10, 0x2e), (0x1f, 0x5b, 0xb5)
    assert tuple(frames[0][250, 500]) == (255 - red[0], 255 - red[1], 255 - red[2])   # the newest chord
    assert tuple(frames[1][250, 500]) == red                  # the red thread, once it is not the newest
    assert tuple(frames[2][500, 750]) == blue                 # the blue thread
    assert tuple(frames[2][500, 500]) == blue                 # where they cross, blue lies on top
    assert tuple(frames[2][250, 500]) == red
    assert tuple(frames[2][100, 900]) == (255, 255, 255)     # the board



def test_the_plan_records_the_texture_weight_it_used(picture):
    """The texture term is for light boards: on a dark one the plan uses none, and says so."""
    from stringbot.planner.colour.model import TEXTURE

    light = plan_colour(picture, colors=["#141414", "#c8102e"], pins=40, size=48, lines=60, cache=False)
    dark = plan_colour(picture, colors=["#ffffff", "#c8102e"], background="#000000", pins=40, size=48, lines=60,
                       cache=False)
    assert light.parameters["texture"] == TEXTURE
    assert dark.parameters["texture"] == 0.0
