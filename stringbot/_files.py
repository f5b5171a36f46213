"""Output files the user can trust: checked before any work, written durably, both or neither.

Every output (``-o``, ``--preview``, ``--record``, ``--journal``) goes through
:func:`check_output_path` before the work starts and :func:`write_atomic` (or
:func:`write_all_atomic`) at the end:

* a symlink to a regular file (or to a place where one may be made) is written
  *through*: the link stays, its target gets the new content;
* a device node, a FIFO, a socket or a folder -- directly or behind a symlink --
  is refused with one line (:class:`BadInput`), never replaced or opened;
* ``-`` (standard output) only where the command allows it;
* a temp file in the target's folder, fsync, ``os.replace``: readers see the old
  file or the new one, never half; a full disk, a read-only folder or a refused
  permission is one line naming the path and the problem (:class:`BadInput`),
  with nothing on disk changed;
* new files get ``0666`` less the umask (as ``open()`` would), existing ones keep
  their mode;
* an existing file is replaced only when stringbot wrote it as the same kind of
  output (:func:`check_ours`): a plan over a plan, a picture stringbot drew over
  such a picture, G-code over stringbot's G-code, a record over a record; never
  a user's picture, a journal, someone's G-code or any other file.  An empty
  file holds nothing to lose and may be replaced.

How a file is known as stringbot's (:func:`written_by_stringbot`):

``plan``
    JSON whose ``format`` is ``"stringbot-plan"``.
``png``
    A PNG carrying the ``tEXt`` chunk ``Software`` = ``stringbot ...``
    (:func:`mark_png`, added to every preview and drawing).  A PNG written
    before that marker existed is taken as stringbot's when it is square (as
    every preview and drawing is) and a stringbot plan of the same name lies
    beside it (``x.png`` beside ``x.json``, the preview's default name) whose
    source picture it is not: re-planning or re-rendering over an old preview
    keeps working, a photo that happens to share a plan's name is refused.
``gcode``
    Text that starts with ``; stringbot winding job``.
``record``
    JSON with a ``wraps`` list and ``collisions`` (a simulated world's record).
``by-hand``
    JSON whose ``format`` is ``"stringbot-by-hand"`` (the position ``stringbot by-hand`` keeps).
"""

import errno
import os
import stat
import tempfile
from pathlib import Path

from .errors import BadInput

__all__ = ["write_atomic", "write_all_atomic", "check_output_path", "check_not_same_file", "problem",
           "output_error", "default_mode", "STDOUT", "check_ours", "written_by_stringbot", "describe", "mark_png",
           "check_suffix", "sha256_file", "GCODE_HEAD", "PINS_HEAD", "ANIMATION_COMMENT"]

STDOUT = "-"

_KINDS = ((stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a FIFO"),
          (stat.S_ISSOCK, "a socket"), (stat.S_ISDIR, "a folder"))


def problem(exc):
    """What an ``OSError`` means for a file, in a few words."""
    code = getattr(exc, "errno", None)
    if code in (errno.ENOSPC, getattr(errno, "EDQUOT", -1)):
        return "the disk is full"
    if code == errno.EROFS:
        return "the file system is read-only"
    if code in (errno.EACCES, errno.EPERM):
        return "permission denied"
    if code == errno.ENOENT:
        return "no such file or folder"
    return (exc.strerror or str(exc) or type(exc).__name__).rstrip(".").lower()


def output_error(path, exc, *, what="output"):
    """The :class:`BadInput` for an ``OSError`` while writing ``path``."""
    return BadInput(f"cannot write {what} {str(path)!r}: {problem(exc)}; nothing was changed there")


def _target(path):
    """The file a write to ``path`` lands in: through symlinks, to the final name."""
    if os.path.islink(path):
        return Path(os.path.realpath(path))
    return Path(path)


def check_output_path(path, *, what="output", allow_stdout=False):
    """Check that ``path`` can be written as a regular file, before any work is done.

    Returns
    -------
    Path or str
        The path (``"-"`` unchanged when allowed).

    Raises
    ------
    BadInput
        ``-`` where standard output makes no sense; a folder, device node, FIFO or
        socket (directly or through a symlink); a folder that does not exist.
    """
    if str(path) == STDOUT:
        if allow_stdout:
            return STDOUT
        raise BadInput(f"{what} path '-': this command cannot write to standard output; expected a file path")
    path = Path(path)
    target = _target(path)
    via = f" (through the symlink {str(path)!r})" if target != path else ""
    try:
        st = os.stat(target)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise BadInput(f"{what} path {str(target)!r}{via} cannot be checked: {problem(exc)}") from None
    if st is not None and not stat.S_ISREG(st.st_mode):
        kind = next(name for test, name in _KINDS + ((lambda m: True, "not a regular file"),) if test(st.st_mode))
        if kind == "a folder" and not via:
            raise BadInput(f"{what} path {str(path)!r} is a folder; expected a file path")
        raise BadInput(f"{what} path {str(target)!r}{via} is {kind}; expected a regular file (not replacing it)")
    parent = target.parent if str(target.parent) else Path(".")
    if not parent.is_dir():
        raise BadInput(f"{what} folder {str(parent)!r} does not exist; create it first")
    try:                      # a read-only folder or a refused permission shows now, not after the work
        fd, probe = tempfile.mkstemp(dir=parent, prefix=f".{target.name}.", suffix=".probe")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise output_error(path, exc, what=what) from None
    return path


def check_not_same_file(output, source, *, what="output", source_what="input"):
    """Refuse to write ``output`` when it names the same file as ``source``.

    Compared by the file itself when both exist (symlinks, hard links, ``./x`` vs ``x``), else by
    resolved path (two outputs that do not exist yet).

    Raises
    ------
    BadInput
        ``"<what> path '<output>' is the <source_what> itself; expected another file"``.
    """
    if str(output) == STDOUT:
        return
    out, src = Path(output), Path(source)
    try:
        same = os.path.samefile(out, src) if out.exists() and src.exists() else out.resolve() == src.resolve()
    except OSError:
        same = False
    if same:
        raise BadInput(f"{what} path {str(output)!r} is the {source_what} itself; expected another file")


#: The first line of every G-code program stringbot writes (``motion.gcode``).
GCODE_HEAD = "; stringbot winding job"
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: The tEXt chunk that marks a PNG as drawn by stringbot: keyword, text prefix.
PNG_SOFTWARE = (b"Software", b"stringbot")
#: What an existing file must be for each kind of output to replace it.
_KIND_NAMES = {"plan": "a plan stringbot wrote", "png": "a picture stringbot drew",
               "gcode": "G-code stringbot wrote", "record": "a simulated world's record",
               "by-hand": "a by-hand position stringbot wrote", "pins": "a pin list stringbot wrote",
               "template": "a template stringbot drew", "animation": "an animation stringbot made"}
#: The first line of a pin list (``.txt``; a ``.csv`` has it after ``# ``).
PINS_HEAD = "stringbot pin list"
#: What marks a GIF or MP4 stringbot made: its comment (GIF comment extension, MP4 ``comment`` metadata).
ANIMATION_COMMENT = b"made by stringbot"
_HEAD = 1 << 16          # a PNG's marker sits right after its header; a journal's header is its first line
_MAX_JSON = 1 << 28      # a larger file is no plan or record of ours (a 2000-pin plan of 100000 lines: ~2 MB)


def check_suffix(path, suffixes, *, option="-o"):
    """Refuse a file name that does not end in one of ``suffixes`` (e.g. ``(".png",)``): stringbot writes
    the format the name promises, never PNG bytes under a ``.jpg`` name.

    Raises
    ------
    BadInput
        ``"-o 'photo.jpg'; expected a file name ending in .png"``.
    """
    if str(path) == STDOUT or os.path.splitext(str(path))[1].lower() not in suffixes:
        raise BadInput(f"{option} {str(path)!r}; expected a file name ending in {' or '.join(suffixes)}")


def mark_png(data):
    """``data`` (PNG bytes) with the ``Software = stringbot <version>`` tEXt chunk after its header.

    The marker is what :func:`written_by_stringbot` looks for before replacing a PNG.  Bytes that
    are not a PNG, or are marked already, come back unchanged.
    """
    import zlib

    from . import __version__

    data = bytes(data)
    if not data.startswith(_PNG_SIGNATURE) or data[12:16] != b"IHDR" or _png_text(data).get(PNG_SOFTWARE[0]):
        return data
    end = 8 + 12 + int.from_bytes(data[8:12], "big")      # after the IHDR chunk
    body = PNG_SOFTWARE[0] + b"\0" + PNG_SOFTWARE[1] + b" " + __version__.encode("latin-1")
    chunk = len(body).to_bytes(4, "big") + b"tEXt" + body + zlib.crc32(b"tEXt" + body).to_bytes(4, "big")
    return data[:end] + chunk + data[end:]


def _png_text(head):
    """``{keyword: text}`` of the tEXt chunks before the image data in ``head`` (a PNG's first bytes)."""
    out, at = {}, 8
    while at + 8 <= len(head):
        n, kind = int.from_bytes(head[at:at + 4], "big"), head[at + 4:at + 8]
        if kind in (b"IDAT", b"IEND"):
            break
        if kind == b"tEXt":
            key, _, text = head[at + 8:at + 8 + n].partition(b"\0")
            out[key] = text
        at += 12 + n
    return out


def _read_head(path):
    try:
        with open(path, "rb") as f:
            return f.read(_HEAD)
    except OSError:
        return None


def _read_tail(path):
    try:
        with open(path, "rb") as f:
            f.seek(max(0, os.path.getsize(path) - _HEAD))
            return f.read(_HEAD)
    except OSError:
        return b""


def _json(path):
    import json
    try:
        if os.path.getsize(path) > _MAX_JSON:
            return None
        with open(path, "rb") as f:
            doc = json.load(f)
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) else None


def _is_plan(path):
    doc = _json(path)
    return doc is not None and doc.get("format") == "stringbot-plan"


def sha256_file(path):
    """The sha256 of the file at ``path``, hex (read in 1 MB blocks)."""
    import hashlib
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _old_preview(path, head):
    """A square PNG without the marker beside a stringbot plan of its name that it is not the source of:
    a preview (or drawing) stringbot wrote before PNGs were marked."""
    if head[12:16] != b"IHDR" or head[16:20] != head[20:24]:
        return False
    stem = os.path.splitext(str(path))[0]            # the preview's default is the plan's name with .png
    doc = next((d for d in map(_json, (stem + ".json", stem)) if d and d.get("format") == "stringbot-plan"), None)
    if doc is None:
        return False
    source = doc.get("source") if isinstance(doc.get("source"), dict) else {}
    try:
        return source.get("sha256") != sha256_file(path)
    except OSError:
        return False


def written_by_stringbot(path, kind):
    """Whether the existing file ``path`` is an output of ``kind`` that stringbot wrote (see the module
    notes): one of the kinds of :func:`check_ours`."""
    if kind == "plan":
        return _is_plan(path)
    if kind == "record":
        doc = _json(path)
        return doc is not None and isinstance(doc.get("wraps"), list) and "collisions" in doc
    if kind == "by-hand":
        doc = _json(path)
        return doc is not None and doc.get("format") == "stringbot-by-hand"
    head = _read_head(path)
    if head is None:
        return False
    if kind == "pins":
        line = head.split(b"\n", 1)[0].decode("utf-8", "replace")
        return line.startswith(PINS_HEAD) or line.startswith("# " + PINS_HEAD)
    if kind == "template":      # motion.drawing's SVG title / PDF producer (its Info sits at the end)
        if head.startswith(b"<?xml") or head.startswith(b"<svg"):
            return b"<title>stringbot " in head
        return head.startswith(b"%PDF") and b"/Producer (stringbot)" in _read_tail(path)
    if kind == "animation":     # the GIF's comment comes before its frames; an MP4's metadata at its end
        return ANIMATION_COMMENT in head or ANIMATION_COMMENT in _read_tail(path)
    if kind == "gcode":
        return head.startswith(GCODE_HEAD.encode())
    if kind == "png":
        if not head.startswith(_PNG_SIGNATURE):
            return False
        return _png_text(head).get(PNG_SOFTWARE[0], b"").startswith(PNG_SOFTWARE[1]) or _old_preview(path, head)
    raise ValueError(f"kind {kind!r}; expected one of {', '.join(_KIND_NAMES)}")


_MAGIC = ((_PNG_SIGNATURE, "a PNG picture"), (b"\xff\xd8\xff", "a JPEG picture"), (b"GIF8", "a GIF picture"),
          (b"II*\0", "a TIFF picture"), (b"MM\0*", "a TIFF picture"), (b"BM", "a BMP picture"),
          (b"%PDF", "a PDF"), (b"<svg", "an SVG picture"), (b"<?xml", "an XML file"))


def describe(path):
    """What the existing file ``path`` is, in a few words (``"a winding journal"``, ``"a JPEG picture"``);
    None when it is none of the kinds known here."""
    head = _read_head(path) or b""
    if head.startswith(b"{"):
        line = head.split(b"\n", 1)[0]
        if b'"stringbot-journal"' in line:
            return "a winding journal"
        if written_by_stringbot(path, "plan"):
            return "a stringbot plan"
        if written_by_stringbot(path, "record"):
            return "a simulated world's record"
        if written_by_stringbot(path, "by-hand"):
            return "a by-hand position"
        return "a JSON file stringbot did not write"
    if head.startswith(GCODE_HEAD.encode()):
        return "G-code stringbot wrote"
    if head[4:12] in (b"ftypisom", b"ftypmp42") or head[4:8] == b"ftyp":
        return "a video"
    for magic, name in _MAGIC:
        if head.startswith(magic):
            if magic == _PNG_SIGNATURE and written_by_stringbot(path, "png"):
                return "a picture stringbot drew"
            return name
    return None


def check_ours(path, kind, *, what, instead):
    """Refuse to replace the file at ``path`` unless stringbot wrote it as ``kind`` (or it is empty).

    Call it before any work, after :func:`check_output_path`.  A path that does not exist (or
    ``-``) passes.

    Parameters
    ----------
    path : str or Path
    kind : {"plan", "png", "gcode", "record", "by-hand", "pins", "template", "animation"}
    what : str
        The output's name in the message (``"plan"``, ``"preview"``).
    instead : str
        What to do instead, e.g. ``"give another -o"``.

    Raises
    ------
    BadInput
        ``"<what> path 'x' exists and is <what it is>, not <kind's name>; not replacing it: <instead>
        (or remove that file)"``.
    """
    if str(path) == STDOUT:
        return
    target = _target(Path(path))
    try:
        if not target.is_file() or target.stat().st_size == 0:
            return
    except OSError:
        return
    if written_by_stringbot(target, kind):
        return
    it = describe(target)
    it = f"is {it}, not" if it else "is not"
    raise BadInput(f"{what} path {str(path)!r} exists and {it} {_KIND_NAMES[kind]}; not replacing it: {instead} "
                   "(or remove that file)")


def default_mode(path):
    """Keep an existing file's mode; a new file gets 0666 less the umask, as open() would."""
    try:
        return os.stat(path).st_mode & 0o7777
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def _fsync_dir(folder):
    try:  # make the rename itself durable
        dfd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    except OSError:
        pass


def _write_temp(target, data):
    """A fsync'd temp file beside ``target`` holding ``data``; its path."""
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, default_mode(target))
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
    except BaseException:
        _unlink(tmp)
        raise
    return tmp


def _unlink(path):
    try:
        os.unlink(path)
    except OSError:
        pass


def write_atomic(path, data, *, what="output"):
    """Write ``data`` (bytes or str) to ``path`` so that readers see old or new, never half.

    Raises
    ------
    BadInput
        The path is not a place for a regular file, or the write failed (full disk,
        read-only folder, permission): one line naming the path and the problem; the
        old file is left untouched.
    """
    write_all_atomic([(path, data, what)])


def write_all_atomic(items):
    """Write several files, all or none: ``items`` is ``[(path, data, what), ...]``.

    Every file is first written beside its target and fsync'd (where a full disk or a
    refused permission shows); only then are they renamed into place.  Should a rename
    fail, the files already replaced are put back as they were.

    Raises
    ------
    BadInput
        As :func:`write_atomic`; nothing on disk is changed.
    """
    prepared = []             # (target, tmp, what)
    try:
        for path, data, what in items:
            check_output_path(path, what=what)
            target = _target(Path(path))
            if isinstance(data, str):
                data = data.encode("utf-8")
            try:
                prepared.append((target, _write_temp(target, data), what))
            except OSError as exc:
                raise output_error(path, exc, what=what) from None
        backups, done = [], []  # (target, backup or None) of the files already replaced
        try:
            for target, tmp, what in prepared:
                backup = None
                try:
                    if len(prepared) > 1 and target.exists():
                        backup = tempfile.mktemp(dir=target.parent, prefix=f".{target.name}.", suffix=".old")
                        os.link(target, backup)
                        backups.append(backup)
                    os.replace(tmp, target)
                except OSError as exc:
                    raise output_error(target, exc, what=what) from None
                done.append((target, backup))
        except BaseException:
            for target, backup in reversed(done):
                if backup is not None:
                    os.replace(backup, target)
                else:
                    _unlink(target)
            raise
        finally:
            for backup in backups:
                _unlink(backup)
        for folder in {t.parent for t, _, _ in prepared}:
            _fsync_dir(folder)
    finally:
        for _target_path, tmp, _ in prepared:
            if os.path.exists(tmp):
                _unlink(tmp)
