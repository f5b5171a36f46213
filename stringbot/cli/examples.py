"""Examples at the foot of every command's ``--help`` (click's epilog), kept in one place.

They run as written from a fresh clone, after the quick start (which writes
``camera.json``); docs/*.md have the same and more.
"""

from . import cli

DOCS = ("Docs: README.md (start here), docs/design.md (how it fits together), docs/planner.md, "
        "docs/machines.md, docs/winding.md, docs/simulator.md, docs/dynamixel.md, docs/maker.md.")

EXAMPLES = {
    "": """\b
Examples:
  stringbot plan examples/camera.png -o camera.json
  stringbot wind camera.json --machine grbl-ring --yes --record camera-record.json
  stringbot COMMAND --help""",
    "plan": """\b
Examples:
  stringbot plan examples/camera.png -o camera.json
  stringbot plan examples/camera.png -o camera.json --machine grbl-ring --force
  stringbot plan examples/horse.png -o horse.json --style fill --pins 240""",
    "render": """\b
Examples:
  stringbot render camera.json -o camera-big.png --size 2001""",
    "score": """\b
Examples:
  stringbot score camera.json
  stringbot score camera.json examples/camera.png --json""",
    "machines": """\b
Examples:
  stringbot machines
  stringbot machines show grbl-ring
  stringbot machines show grbl-ring > mine.toml     (your own machine file: edit it, check it)""",
    "machines show": """\b
Examples:
  stringbot machines show grbl-ring
  stringbot machines show grbl-ring > mine.toml && stringbot machines show ./mine.toml""",
    "machines check": """\b
Examples:
  stringbot machines check grbl-ring                  (the simulated machine: all agree)
  stringbot machines check grbl-ring --port /dev/ttyUSB0 --apply""",
    "gcode": """\b
Examples:
  stringbot gcode camera.json --machine grbl-ring -o camera.gcode
  stringbot gcode camera.json --machine grbl-ring -o - | head -30""",
    "estimate": """\b
Examples:
  stringbot estimate camera.json --machine grbl-ring
  stringbot estimate camera.json --machine grblhal-ring --json
  stringbot estimate cat.json                 (a plan made with --machine: that machine)""",
    "wind": """\b
Examples:
  stringbot wind camera.json --machine grbl-ring --yes --record camera-record.json   (a dry run)
  stringbot wind camera.json --machine grbl-ring --port /dev/ttyUSB0
  stringbot wind camera.json --machine fluidnc-ring --port socket://192.168.1.50:23
  stringbot wind camera.json --machine grbl-ring --port /dev/ttyUSB0 --resume
  stringbot wind camera.json --machine grbl-ring --status
  stringbot wind cat.json --port /dev/ttyUSB0 --yes   (the plan's machine; a colour plan stops at each
                                                       spool change, exit 3, with the resume command)""",
    "calibrate": """\b
Examples:
  stringbot calibrate sheet --machine grbl-ring -o sheet.json
  stringbot calibrate fit sheet-photo.jpg --machine grbl-ring --sheet sheet.json -o mine.toml""",
    "calibrate sheet": """\b
Examples:
  stringbot calibrate sheet --machine grbl-ring -o sheet.json                  (and sheet.pdf, to print)
  stringbot calibrate sheet --machine grbl-ring -o sheet.json --template sheet.svg""",
    "calibrate fit": """\b
Examples:
  stringbot calibrate fit sheet-photo.jpg --machine grbl-ring --sheet sheet.json -o mine.toml
  stringbot plan examples/camera.png -o camera.json --machine mine.toml     (planned with the fitted thread)""",
    "simulate": """\b
Examples:
  stringbot simulate --machine grbl-ring --pty /tmp/ring
  stringbot simulate --machine grbl-ring --pty /tmp/ring --faults power@500,reset@2000
  stringbot simulate --pty /tmp/ring --tie-on crimson --pin 42   (your hands at that running simulator)""",
    "serve": """\b
Examples:
  stringbot serve                                   (then open http://127.0.0.1:8000/)
  stringbot serve --port 8080 --plans ~/string-art
  stringbot serve --host 0.0.0.0                    (the workshop's other computers too: no password)""",
}


def _apply():
    for path, text in EXAMPLES.items():
        cmd = cli
        for name in path.split():
            cmd = cmd.commands[name]
        cmd.epilog = text + ("\n\n" + DOCS if path == "" else "")


_apply()
