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
  their mode.
"""

import errno
import os
import stat
import tempfile
from pathlib import Path

from .errors import BadInput

__all__ = ["write_atomic", "write_all_atomic", "check_output_path", "check_not_same_file", "problem",
           "output_error", "default_mode", "STDOUT"]

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
