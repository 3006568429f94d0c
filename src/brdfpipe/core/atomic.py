"""Atomic outputs: the one home of every "write to a temporary sibling, then rename".

A reader (or a rerun of the workflow) never sees a half-written output: a
file or folder either does not exist, is the complete earlier version, or is
the complete new one.  Every writer of the library goes through this module:

* :func:`atomic_path` (context manager) hands out a temporary file name next
  to the output and renames it into place when the block succeeds;
  :func:`atomic_write`, :func:`write_text`, :func:`write_bytes` and
  :func:`save_npz` are built on it.
* :func:`atomic_dir` does the same for a folder output (a Zarr group): the
  folder is built under a temporary name and swapped in by
  :func:`replace_dir`, which replaces only what the caller recognises as its
  own kind of output (``replaceable``) or an empty folder, never a foreign
  folder.  On any error the earlier output is left exactly as it was.
* Temporary names are ``.NAME.TAG-PID-RANDOM``.  A process killed with
  SIGKILL can leave one behind; the next writer of the same output removes
  such siblings whose process is gone (:func:`clean_stale_siblings`).
* :func:`check_not_input` refuses an output path that names one of the
  command's inputs; :func:`check_writable` refuses, before any work, an
  output whose folder cannot be written (permissions, a read-only file
  system); :func:`output_of` maps a temporary name back to its output for
  error messages.
* A workflow job holds a *lease* on its log file (:func:`job_lease`, taken by
  :func:`brdfpipe.core.logutil.log_to`): before each rename into place the
  writer checks that the log path still names the file it opened.  Snakemake
  deletes a job's log before it starts the job again, so a process of an
  earlier attempt that outlived its run (the main process killed alone, a
  Slurm step that survived ``scancel``, a node that came back) cannot put
  its outputs over the new attempt's: it stops with :class:`SupersededError`
  at its next rename.  The outputs of a superseded job are missing, never
  stale (its Snakemake wrapper may remove files when it fails; the next run
  rebuilds what is missing).  The check and the rename are two system calls:
  the window between them is a few microseconds, against minutes or hours
  of a late process.

Files are fsync'ed before the rename and the folder after it, so a power cut
leaves the old or the new version, not an empty file.
"""

from __future__ import annotations

import errno
import logging
import os
import re
import secrets
import shutil
import tempfile
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

__all__ = [
    "OutputError",
    "SupersededError",
    "job_lease",
    "check_lease",
    "tmp_sibling",
    "remove_tree",
    "clean_stale_siblings",
    "atomic_path",
    "atomic_write",
    "write_text",
    "write_bytes",
    "save_npz",
    "atomic_dir",
    "replace_dir",
    "check_replaceable",
    "check_not_input",
    "is_out_of_space",
    "output_of",
    "check_writable",
    "existing_ancestor",
]

logger = logging.getLogger("brdfpipe.core.atomic")

#: Temporary sibling tags used by the library (``.NAME.TAG-PID-RANDOM``).
_TAGS = ("tmp", "old", "rows")
_SIBLING = re.compile(r"^\.(?P<name>.+)\.(?P<tag>[a-z]+)-(?P<pid>\d+)-[0-9a-f]{8}$")
#: The same, with the extension :func:`atomic_path` may append (``suffix``).
_SIBLING_ANY = re.compile(r"^\.(?P<name>.+)\.(?P<tag>[a-z]+)-(?P<pid>\d+)-[0-9a-f]{8}(?:\.[A-Za-z0-9]{1,8})?$")


class OutputError(ValueError):
    """An output path cannot be written safely (it names an input, or a foreign folder)."""


class SupersededError(OutputError):
    """This process's job was started again by a newer run (its log file was replaced): its outputs are discarded."""


#: The lease of the running workflow job: (log path, device, inode) of the log file it opened; None outside a job.
_lease: tuple[Path, int, int] | None = None


@contextmanager
def job_lease(log: str | os.PathLike[str], opened: os.stat_result) -> Iterator[None]:
    """Hold the lease on ``log`` (the job's log file, ``opened`` = ``os.fstat`` of its open handle) for the block.

    Inside the block every rename into place first calls :func:`check_lease`.
    """
    global _lease
    previous = _lease
    _lease = (Path(log), opened.st_dev, opened.st_ino)
    try:
        yield
    finally:
        _lease = previous


def check_lease() -> None:
    """Raise :class:`SupersededError` if the held lease's log path no longer names the file the job opened.

    No lease held (the command line, tests, the Snakemake process): nothing to check.
    """
    if _lease is None:
        return
    log, dev, ino = _lease
    try:
        st = os.stat(log)
        same = (st.st_dev, st.st_ino) == (dev, ino)
    except FileNotFoundError:
        same = False
    if not same:
        raise SupersededError(
            f"{log}: this job was started again by a newer run (its log file was replaced); "
            "this process stops and leaves the outputs to it"
        )


def tmp_sibling(out: str | os.PathLike[str], tag: str = "tmp") -> Path:
    """A fresh, unused name next to ``out`` (same file system, so the rename is atomic)."""
    out = Path(out)
    return out.parent / f".{out.name}.{tag}-{os.getpid()}-{secrets.token_hex(4)}"


def remove_tree(path: str | os.PathLike[str]) -> None:
    """Remove a file, link or directory tree; missing is fine."""
    path = Path(path)
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def clean_stale_siblings(out: str | os.PathLike[str]) -> list[Path]:
    """Remove temporary siblings of ``out`` left by killed writers; returns what was removed.

    Only names this module makes (``.NAME.TAG-PID-RANDOM`` with a known tag)
    are considered, and only when no process with that PID runs on this host.
    """
    out = Path(out)
    removed: list[Path] = []
    try:
        entries = list(out.parent.iterdir())
    except OSError:
        return removed
    for entry in entries:
        m = _SIBLING.match(entry.name)
        if not m or m["name"] != out.name or m["tag"] not in _TAGS:
            continue
        if _pid_alive(int(m["pid"])):
            continue
        remove_tree(entry)
        removed.append(entry)
    if removed:
        logger.info("removed %d temporary sibling(s) of %s left by an interrupted run", len(removed), out)
    return removed


def _fsync_dir(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _refuse_folder(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        raise OutputError(f"{path}: is a folder; refusing to replace it with a file")


@contextmanager
def atomic_path(path: str | os.PathLike[str], *, suffix: str = "") -> Iterator[Path]:
    """Yield a temporary file name next to ``path``; on success rename it to ``path``.

    The folder is created if needed.  The file gets mode 0644, is fsync'ed
    and renamed over ``path``; on any error (or an interrupt) the temporary
    file is removed, the error propagates and an earlier ``path`` is
    untouched.  ``suffix`` is appended to the temporary name for writers
    that insist on an extension (``np.savez`` adds ``.npz`` otherwise).
    A folder at ``path`` is refused (:class:`OutputError`).
    """
    path = Path(path)
    _refuse_folder(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    clean_stale_siblings(path)
    tmp = tmp_sibling(path)
    if suffix:
        tmp = tmp.with_name(tmp.name + suffix)
    try:
        yield tmp
        if not tmp.is_file():
            raise FileNotFoundError(f"{tmp}: the writer of {path} wrote no file")
        os.chmod(tmp, 0o644)
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        check_lease()
        os.replace(tmp, path)
        _fsync_dir(path.parent)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_write(path: str | os.PathLike[str], write: Callable[[Any], None], binary: bool = True) -> None:
    """Call ``write(fh)`` on a temporary file next to ``path``, then rename it to ``path``.

    Text mode is UTF-8 without newline translation.  See :func:`atomic_path`.
    """
    with atomic_path(path) as tmp:
        mode = "wb" if binary else "w"
        kwargs: dict[str, Any] = {} if binary else {"encoding": "utf-8", "newline": ""}
        with open(tmp, mode, **kwargs) as fh:
            write(fh)


def write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    atomic_write(path, lambda fh: fh.write(text), binary=False)


def write_bytes(path: str | os.PathLike[str], data: bytes | bytearray | memoryview | Iterable[bytes]) -> None:
    """Write ``data`` (bytes, or an iterable of byte chunks) to ``path`` atomically."""

    def write(fh: Any) -> None:
        if isinstance(data, (bytes, bytearray, memoryview)):
            fh.write(data)
        else:
            for part in data:
                fh.write(part)

    atomic_write(path, write)


def save_npz(path: str | os.PathLike[str], arrays: dict[str, Any], *, compressed: bool = False) -> None:
    """``np.savez`` (or ``savez_compressed``) of ``arrays`` to ``path`` atomically."""
    import numpy as np

    save = np.savez_compressed if compressed else np.savez
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        save(fh, **arrays)


def replace_dir(
    tmp: str | os.PathLike[str], out: str | os.PathLike[str], *, replaceable: Callable[[Path], bool]
) -> None:
    """Rename the finished folder ``tmp`` to ``out``, replacing an earlier output.

    An existing ``out`` is replaced only if it is an empty folder or
    ``replaceable(out)`` is true (the caller recognises it as an earlier
    output of the same kind); anything else — a file, a link, a foreign
    folder or Zarr group — is refused with :class:`OutputError` and left
    untouched.  The earlier output is first renamed aside and deleted only
    after the new one is in place, so ``out`` is at every moment absent,
    the old output or the new one.
    """
    tmp, out = Path(tmp), Path(out)
    check_lease()
    old: Path | None = None
    if out.is_symlink() or out.exists():
        check_replaceable(out, replaceable=replaceable)
        old = tmp_sibling(out, "old")
        os.rename(out, old)
    try:
        os.rename(tmp, out)
    except BaseException:
        if old is not None:
            os.rename(old, out)
        raise
    _fsync_dir(out.parent)
    if old is not None:
        remove_tree(old)


def check_replaceable(out: str | os.PathLike[str], *, replaceable: Callable[[Path], bool]) -> None:
    """Raise :class:`OutputError` unless ``out`` is absent, an empty folder or ``replaceable``."""
    out = Path(out)
    if not (out.is_symlink() or out.exists()):
        return
    if out.is_dir() and not out.is_symlink():
        try:
            empty = not any(out.iterdir())
        except OSError:
            empty = False
        if empty or replaceable(out):
            return
        raise OutputError(
            f"{out}: exists and is not an output of this kind; refusing to replace it "
            "(remove it yourself or choose another path)"
        )
    raise OutputError(f"{out}: exists and is not a folder; refusing to replace it")


@contextmanager
def atomic_dir(out: str | os.PathLike[str], *, replaceable: Callable[[Path], bool]) -> Iterator[Path]:
    """Yield a fresh temporary folder next to ``out``; on success swap it in with :func:`replace_dir`.

    ``out`` is checked before any work starts (a foreign folder is refused
    at once, not after minutes of computing).  On any error the temporary
    folder is removed and the earlier ``out`` stays as it was.
    """
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    check_replaceable(out, replaceable=replaceable)
    clean_stale_siblings(out)
    tmp = tmp_sibling(out)
    tmp.mkdir()
    try:
        yield tmp
        replace_dir(tmp, out, replaceable=replaceable)
    except BaseException:
        remove_tree(tmp)
        raise


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def check_not_input(
    out: str | os.PathLike[str], inputs: Iterable[str | os.PathLike[str] | None], *, what: str = "--out"
) -> None:
    """Raise :class:`OutputError` if writing ``out`` would replace one of ``inputs``.

    That is: ``out`` names the same file or folder as an input (also through
    a link or another spelling), or ``out`` is a folder that contains an
    input (replacing it would delete the input).  Writing a new file inside
    an input folder is allowed.
    """
    out_p = Path(out)
    out_r = out_p.resolve()
    for inp in inputs:
        if inp is None:
            continue
        in_p = Path(inp)
        in_r = in_p.resolve()
        if out_r == in_r or _same_file(out_p, in_p) or out_r in in_r.parents:
            raise OutputError(f"{what} {out}: would write over the input {inp}; choose another output path")


def is_out_of_space(err: BaseException) -> bool:
    """True for the OS errors of a full disk or quota."""
    return isinstance(err, OSError) and err.errno in (errno.ENOSPC, errno.EDQUOT)


def output_of(path: str | os.PathLike[str]) -> Path:
    """The output a temporary sibling (``.NAME.TAG-PID-RANDOM[.SUFFIX]``) stands for; other paths unchanged.

    Error messages name the output the user asked for, not the hidden
    temporary name an OS error carries.
    """
    p = Path(path)
    m = _SIBLING_ANY.match(p.name)
    if m and m["tag"] in _TAGS:
        return p.parent / m["name"]
    return p


def existing_ancestor(path: str | os.PathLike[str]) -> Path:
    """``path`` (made absolute) or its nearest ancestor that exists."""
    p = Path(os.path.abspath(path))
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def check_writable(out: str | os.PathLike[str], *, what: str = "--out", inside: bool = False) -> None:
    """Raise :class:`OutputError` unless a file can be created where ``out`` will be written.

    The folder probed is ``out``'s parent (``inside``: ``out`` itself, for a
    command that writes into an existing folder), or its nearest existing
    ancestor when it does not exist yet.  A file is created there and
    removed at once, so permissions, a read-only file system and a full
    inode table are all seen before any work starts; nothing else is
    written.  The message names the option and the folder.
    """
    out = Path(out)
    folder = out if inside and out.is_dir() else out.parent
    probe_dir = existing_ancestor(folder)
    if not probe_dir.is_dir():
        raise OutputError(f"{what} {out}: {probe_dir} is not a folder; cannot write there")
    try:
        fd, name = tempfile.mkstemp(prefix=".brdfpipe-probe-", dir=probe_dir)
    except OSError as err:
        why = err.strerror or type(err).__name__
        raise OutputError(f"{what} {out}: cannot write in {probe_dir} ({why}); nothing was written") from None
    os.close(fd)
    os.unlink(name)
