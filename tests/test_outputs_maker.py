"""`pins`, `template`, `animate` and `calibrate sheet --template` replace only what stringbot wrote.

Through the real entry point in a scratch folder: a user's notes, PDF, SVG or video under the output's
name is refused (exit 2, one line naming what the file is, every file byte-for-byte unchanged); the
command's own output is replaced when it runs again.
"""

import pytest

from test_cli_plan import picture, private_cache, run  # noqa: F401  (fixtures)
from test_outputs_ours import QUICK, refused, snapshot

#: (command line with {out}, output name, a user's file of that name, what the refusal calls it)
CASES = [
    (["pins", "p.json", "-o", "{out}"], "list.txt", b"shopping: nails, thread\n", "is not a pin list"),
    (["pins", "p.json", "-o", "{out}"], "list.csv", b"step,pin\n1,2\n", "is not a pin list"),
    (["template", "--machine", "grbl-ring", "-o", "{out}"], "ring.svg",
     b'<?xml version="1.0"?>\n<svg xmlns="http://www.w3.org/2000/svg"><title>my logo</title></svg>\n',
     "is an XML file, not a template"),
    (["template", "--machine", "grbl-ring", "-o", "{out}"], "ring.pdf", b"%PDF-1.4\n% my invoice\n",
     "is a PDF, not a template"),
    (["animate", "p.json", "-o", "{out}", "--frames", "3", "--size", "64"], "wind.gif", b"GIF89a my cat",
     "is a GIF picture, not an animation"),
    (["calibrate", "sheet", "--machine", "grbl-ring", "-o", "s.json", "--template", "{out}"], "sheet.pdf",
     b"%PDF-1.4\n% my invoice\n", "is a PDF, not a template"),
]


@pytest.fixture
def folder(tmp_path, picture):  # noqa: F811
    assert run("plan", "pic.png", "-o", "p.json", *QUICK, cwd=tmp_path)[0] == 0
    return tmp_path


@pytest.mark.parametrize("args, name, theirs, words", CASES, ids=[c[1] for c in CASES])
def test_a_users_file_is_never_replaced_but_our_own_output_is(folder, args, name, theirs, words):
    line = [a.format(out=name) for a in args]
    code, _, err = run(*line, cwd=folder)                  # a new file: written
    assert code == 0, err
    ours = (folder / name).read_bytes()
    before = snapshot(folder)
    code, _, err = run(*line, cwd=folder)                  # its own output: replaced (same content again)
    assert code == 0, err
    assert snapshot(folder).keys() == before.keys() and (folder / name).read_bytes()[:16] == ours[:16]
    (folder / name).write_bytes(theirs)                    # now the user's file under that name
    if name.startswith("sheet"):
        (folder / "s.json").unlink()                       # the sheet's plan is not what this case is about
    err = refused(folder, line, words)
    assert "not replacing it: give another" in err
    assert (folder / name).read_bytes() == theirs


def test_standard_output_is_no_file_to_protect(folder):
    code, out, err = run("pins", "p.json", "-o", "-", cwd=folder)
    assert code == 0 and out.startswith("stringbot pin list")
