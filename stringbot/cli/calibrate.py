"""Calibrating the thread: ``calibrate sheet`` (a test plan and its print), ``calibrate fit`` (a photo of it)."""

import os
import re

import click

from ..errors import BadInput
from . import cli

#: the [thread] keys `calibrate fit` writes, in the order it writes them
KEYS = ("effective_mm", "board_gray", "thread_gray")


@cli.group("calibrate")
def calibrate_cmd():
    """Measure your thread: wind a test sheet, photograph it, fit the thread's width and grays."""


@calibrate_cmd.command("sheet")
@click.option("--machine", required=True, help="The machine that winds the sheet (name or .toml).")
@click.option("-o", "--output", "output", required=True, type=click.Path(path_type=str),
              help="The sheet's plan to write (JSON): wind it with `stringbot wind`.")
@click.option("--template", type=click.Path(path_type=str), default=None,
              help="The print to lay under the threads: .pdf (tiled on pages) or .svg [default: the plan's path "
                   "with .pdf].")
@click.option("--paper", type=click.Choice(["a4", "letter"]), default="a4", show_default=True,
              help="PDF page size.")
@click.option("--force", is_flag=True, help="Overwrite a sheet whose winding journal has steps done.")
def sheet_cmd(machine, output, template, paper, force):
    """Write a calibration sheet for a machine: a small plan of patches of known thread density, and its print."""
    from firmware_protocol.machine import load_machine

    from .._files import check_not_same_file, check_ours, check_output_path, write_all_atomic
    from ..motion import estimate, format_duration
    from ..motion.calibration_sheet import sheet_pdf, sheet_svg
    from ..planner.calibration.sheet import design_sheet, sheet_plan
    from .plan_checks import refuse_a_wound_plan

    template = template or os.path.splitext(output)[0] + ".pdf"
    ext = os.path.splitext(template)[1].lower()
    if ext not in (".pdf", ".svg"):
        raise BadInput(f"--template {template!r}; expected a file name ending in .pdf or .svg")
    check_output_path(output, what="sheet")
    check_ours(output, "plan", what="sheet", instead="give another -o")     # never someone's own file
    check_output_path(template, what="template")
    check_ours(template, "template", what="template", instead="give another --template")
    check_not_same_file(template, output, what="template", source_what="sheet")
    if not force:
        refuse_a_wound_plan(output)
    m = load_machine(machine)
    thread = m["thread.diameter_mm"]
    sheet = design_sheet(pins=m.pins, diameter_mm=m["ring.diameter_mm"], pin_diameter_mm=m["ring.pin_diameter_mm"],
                         thread_mm=thread)
    plan = sheet_plan(sheet, machine=machine, name=m.name, thread_mm=m[m.thread_width_key])  # as its plans are
    est = estimate(plan, m)
    data = sheet_svg(sheet, name=m.name) if ext == ".svg" else sheet_pdf(sheet, name=m.name, paper=paper)
    write_all_atomic([(output, plan.to_json(), "calibration sheet"), (template, data, "template")])
    pages = f", {data.count(b'/Type /Page ')} {paper} page(s)" if ext == ".pdf" else ""
    click.echo(f"calibration sheet for {m.name}: {len(sheet.strips)} patches ("
               + ", ".join(f"{s.name} {s.lines_per_mm:.2f}" for s in sheet.strips)
               + f" lines per mm), {plan.stats['lines']} lines, {est.thread_m:.1f} m of thread, about "
                 f"{format_duration(est.seconds)} of winding -> {output}")
    click.echo(f"template: {2 * sheet.half_mm:.0f} x {2 * sheet.half_mm:.0f} mm{pages} -> {template}")
    click.echo(f"next: print the template at 100 %, lay it under the ring (its pins on the pins, pin 0 at the top), "
               f"stringbot wind {output} --machine {machine} --port PORT, photograph it from the front in even light, then "
               f"stringbot calibrate fit PHOTO --machine {machine} -o mine.toml")


@calibrate_cmd.command("fit")
@click.argument("photo", type=click.Path(path_type=str))
@click.option("--machine", required=True, help="The machine that wound the sheet (name or .toml).")
@click.option("--sheet", "sheet_path", type=click.Path(path_type=str), default=None,
              help="The sheet's plan from `calibrate sheet` [default: the machine's sheet, designed again].")
@click.option("-o", "--output", "output", required=True, type=click.Path(path_type=str),
              help="Machine file to write (.toml): the machine's, with the calibrated [thread] keys; an existing "
                   "one only if it is --machine's own file (calibrated in place) or with --force.")
@click.option("--force", is_flag=True,
              help="Replace an existing machine file that is not --machine's own (its keys and edits are lost).")
def fit_cmd(photo, machine, sheet_path, output, force):
    """Fit the thread's effective width and the board's and thread's grays from a PHOTO of the wound sheet."""
    from firmware_protocol.machine import MachineFileError, bundled_dir, load_machine

    from .._files import check_not_same_file, check_output_path, write_atomic
    from ..planner.calibration.sheet import design_sheet, sheet_from_plan
    from ..planner.calibration.photo import fit_photo
    from ..planner.plan_file import read_plan

    if not output.lower().endswith(".toml"):
        raise BadInput(f"-o {output!r}; expected a machine file name ending in .toml")
    check_output_path(output, what="machine file")
    for src, what in ((photo, "photo"), (sheet_path, "sheet")):
        if src:
            check_not_same_file(output, src, what="machine file", source_what=what)
    if os.path.realpath(os.path.dirname(os.path.abspath(output))) == os.path.realpath(bundled_dir()):
        raise BadInput(f"-o {output!r} is among the bundled machine files; expected a file of your own "
                       "(e.g. -o mine.toml)")
    m = load_machine(machine)
    if os.path.isfile(output) and os.path.getsize(output):
        try:
            load_machine(output)        # a machine file may be replaced: --machine's own, or with --force
        except MachineFileError:
            raise BadInput(f"machine file path {output!r} exists and is not a machine file; not replacing it: "
                           "give another -o (or remove that file)") from None
        if not force and not (m.path and os.path.samefile(output, m.path)):
            raise BadInput(f"machine file {output!r} exists and is not --machine's file ({m.path}); not replacing "
                           f"it with {m.name}'s keys (its own and its edits would be lost): calibrate it in place "
                           f"with --machine {output}, give another -o, or --force to replace it")
    ring = dict(pins=m.pins, diameter_mm=m["ring.diameter_mm"], pin_diameter_mm=m["ring.pin_diameter_mm"])
    if sheet_path:
        plan = read_plan(sheet_path)
        sheet = sheet_from_plan(plan, machine=m.name, where=f"sheet {sheet_path!r}", **ring)
    else:
        sheet = design_sheet(thread_mm=m["thread.diameter_mm"], **ring)
    fit = fit_photo(photo, sheet, what="photo")
    values = {"effective_mm": round(fit.effective_mm, 4), "board_gray": round(fit.board_gray, 4),
              "thread_gray": round(fit.thread_gray, 4)}
    text = calibrated_text(m, values, note=f"`stringbot calibrate fit {os.path.basename(photo)}`")
    write_atomic(output, text, what="machine file")
    nominal = m["thread.diameter_mm"]
    click.echo(f"thread   effective width {fit.effective_mm:.4f} mm ({fit.effective_mm / nominal:.2f} x the "
               f"machine's {nominal:g} mm), gray {fit.thread_gray:.3f} (linear light {fit.thread:.4f})")
    click.echo(f"board    gray {fit.board_gray:.3f} (linear light {fit.board:.4f}); grays are sRGB levels, "
               "0 black, 1 the sheet's white paper")
    click.echo(f"fit      RMS {fit.rms:.4f} (reflectance) over {len(fit.cells)} cells; the bare areas are within "
               f"{100 * fit.light_spread:.1f} % of the fitted light")
    click.echo("patch  lines/mm  covered  photo   model")
    for s in sheet.strips:
        rows = [c for c in fit.cells if c[0] == s.name]
        if rows:
            avg = [sum(c[i] for c in rows) / len(rows) for i in (1, 2, 3)]
            click.echo(f"{s.name:<6} {s.lines_per_mm:>8.2f}  {avg[0]:>7.3f}  {avg[1]:.4f}  {avg[2]:.4f}")
    if fit.rms > 0.02:
        click.echo(f"warning: the photo fits the sheet's threads poorly (RMS {fit.rms:.3f}); check that the light "
                   "is even and without glare, the photo sharp and taken from the front", err=True)
    click.echo(f"-> {output}: plan with it: stringbot plan IMAGE --machine {output}")


def calibrated_text(machine, values, *, note):
    """The text of ``machine``'s file with ``[thread]``'s calibrated ``values`` set (its comments kept).

    The keys are written after the section's last key, replacing any there were; when the file cannot
    be edited so (no ``[thread]`` table), or the edit would not read back as the same machine with
    these values, the checked machine is written out whole (:meth:`Machine.to_toml`).
    """
    import tomllib

    from firmware_protocol.machine import Machine, machine_from_dict

    want = dict(machine.values, **{f"thread.{k}": float(v) for k, v in values.items()})
    new = [f"# calibrated by {note}\n"] + [f"{k} = {values[k]!r}\n" for k in KEYS if k in values]
    try:
        with open(machine.path, encoding="utf-8") as f:
            lines = f.readlines()
    except OSError:
        lines = []
    header = [i for i, line in enumerate(lines) if re.match(r"^\s*\[\s*thread\s*\]\s*(#.*)?$", line)]
    if len(header) == 1:
        start = header[0] + 1
        end = next((i for i in range(start, len(lines)) if re.match(r"^\s*\[", lines[i])), len(lines))
        body = [line for line in lines[start:end]
                if not re.match(rf"^\s*({'|'.join(KEYS)})\s*=", line) and not line.startswith("# calibrated by ")]
        last = max((i for i, line in enumerate(body) if re.match(r"^\s*[A-Za-z_]", line)), default=-1)
        body = body[:last + 1] + new + body[last + 1:]
        text = "".join(lines[:start] + body + lines[end:])
        try:
            if machine_from_dict(tomllib.loads(text), source=machine.path).values == want:
                return text
        except (tomllib.TOMLDecodeError, ValueError):
            pass
    whole = Machine(name=machine.name, path=machine.path, values=want)
    return f"# {machine.name}, calibrated by {note}\n" + whole.to_toml()
