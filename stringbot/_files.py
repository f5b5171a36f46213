"""Durable file writes: a temp file in the same folder, fsync, then ``os.replace``."""

import os
import tempfile
from pathlib import Path

from .errors import BadInput

__all__ = ["write_atomic", "check_output_path", "check_not_same_file"]


def check_output_path(path, *, what="output"):
    """Check that ``path`` can be written as a file, before any work is done.

    Raises
    ------
    BadInput
        If the path is a folder or its folder does not exist.
    """
    path = Path(path)
    if path.is_dir():
        raise BadInput(f"{what} path {str(path)!r} is a folder; expected a file path")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise BadInput(f"{what} folder {str(parent)!r} does not exist; create it first")
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
    out, src = Path(output), Path(source)
    try:
        same = os.path.samefile(out, src) if out.exists() and src.exists() else out.resolve() == src.resolve()
    except OSError:
        same = False
    if same:
        raise BadInput(f"{what} path {str(output)!r} is the {source_what} itself; expected another file")


def _default_mode(path):
    """Keep an existing file's mode; a new file gets 0666 less the umask, as open() would."""
    try:
        return os.stat(path).st_mode & 0o7777
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def write_atomic(path, data):
    """Write ``data`` (bytes or str) to ``path`` so that readers see old or new, never half.

    The folder must exist; on any failure the old file is left untouched.
    """
    path = check_output_path(path)
    if isinstance(data, str):
        data = data.encode("utf-8")
    fd, tmp = tempfile.mkstemp(dir=path.parent or ".", prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, _default_mode(path))
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    try:  # make the rename itself durable
        dfd = os.open(path.parent or ".", os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    except OSError:
        pass
