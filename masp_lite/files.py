"""The one way the product writes a file and the one way it reads a file a user gave it.

* :func:`atomic_write` — every file the product writes (records, weights, training states,
  manifests, pages, plans) is written whole or not at all: the bytes go to a temporary file
  in the same folder, are flushed to disk (``fsync``), and the temporary file is renamed over
  the target in one step. A full disk or a kill mid-write leaves the old file as it was; two
  writers to one path leave one of the two whole files, never a mix. A temporary file left by
  a killed writer (its process gone) is removed the next time that folder is written.
  :func:`atomic_target` is the same for writers that need a path rather than bytes (a movie
  encoder): they write the temporary path, which is renamed when they finish.
* :func:`read_bounded` — a file a user named (a record, a plan, a weights file, a kept
  history) is read only when it is a regular file, and only up to a size limit: a FIFO named
  ``x.json`` or ``/dev/zero`` is refused at once instead of hanging or filling memory.
  :func:`file_bytes` is the same read done once while the file is unchanged, so that a
  file's hash, its checks and its load share one read; :func:`sha256` is its hash.

Both raise one clear error naming the file; :func:`atomic_write` lets the ``OSError`` of a
full disk or a read-only folder through (with the target untouched), so a caller that can go
on (training) decides what to say.
"""
from __future__ import annotations

import contextlib
import hashlib
import os
import stat
from pathlib import Path

__all__ = ["atomic_write", "atomic_target", "read_bounded", "file_bytes", "sha256", "clean_orphans", "TMP_PREFIX",
           "MAX_READ"]

#: The start of every temporary file's name: ``.masp-tmp.PID.RANDOM.NAME`` (it keeps the target's suffix).
TMP_PREFIX = ".masp-tmp."
#: The default size limit of :func:`read_bounded` (records, plans, histories are kilobytes).
MAX_READ = 64 * 2**20


def _tmp_name(path: Path) -> Path:
    return path.with_name(f"{TMP_PREFIX}{os.getpid()}.{os.urandom(4).hex()}.{path.name}")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except PermissionError:  # it runs, as another user
        return True
    except (OSError, OverflowError):
        return False
    return True


def clean_orphans(folder) -> list[Path]:
    """Remove the temporary files in ``folder`` whose writer no longer runs (a killed write); returns them."""
    gone = []
    try:
        entries = list(Path(folder).iterdir())
    except OSError:
        return gone
    for p in entries:
        if not p.name.startswith(TMP_PREFIX):
            continue
        pid = p.name[len(TMP_PREFIX):].split(".", 1)[0]
        if not pid.isdigit() or _alive(int(pid)):
            continue
        with contextlib.suppress(OSError):
            p.unlink()
            gone.append(p)
    return gone


def _fsync_folder(folder: Path) -> None:
    with contextlib.suppress(OSError):  # not every file system lets a folder be opened and synced
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


@contextlib.contextmanager
def atomic_target(path):
    """Yield a temporary path beside ``path`` (same suffix) to write; on success it replaces ``path``.

    On an error the temporary file is removed and ``path`` is left as it was."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{str(path)!r} is a folder; expected a file path to write")
    path.parent.mkdir(parents=True, exist_ok=True)
    clean_orphans(path.parent)
    tmp = _tmp_name(path)
    try:
        yield tmp
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        try:  # a replaced file keeps its permissions; a new one is readable by all, as a plain write makes it
            mode = stat.S_IMODE(os.stat(path).st_mode)
        except OSError:
            mode = 0o644
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    _fsync_folder(path.parent)


def atomic_write(path, data: bytes | str) -> Path:
    """Write ``data`` (bytes, or text as UTF-8) to ``path`` whole or not at all; returns ``path``.

    Temporary file in the same folder, ``fsync``, ``os.replace``: ``path`` holds either its old
    contents or all of ``data``. Orphaned temporary files of killed writers there are removed first."""
    if isinstance(data, str):
        data = data.encode("utf-8")
    path = Path(path)
    with atomic_target(path) as tmp:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "wb") as f:
            f.write(data)  # atomic_target syncs it to disk before the rename
    return path


def read_bounded(path, limit: int = MAX_READ, what: str = "file") -> bytes:
    """The bytes of ``path`` when it is a regular file of at most ``limit`` bytes; else one ValueError.

    Opened without blocking (a FIFO would wait for a writer forever) and checked on the open
    file itself, then read to at most ``limit + 1`` bytes (a file that grows meanwhile, or a
    device such as ``/dev/zero``, cannot fill memory)."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        link = " (a link to a missing file)" if os.path.islink(path) else ""
        raise ValueError(f"{str(path)!r}: expected an existing {what}, found none{link}") from None
    except IsADirectoryError:
        raise ValueError(f"{str(path)!r} is a folder; expected a {what}") from None
    except OSError as e:
        raise ValueError(f"{str(path)!r}: expected a readable {what}, could not open it "
                         f"({e.strerror or type(e).__name__})") from None
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise ValueError(f"{str(path)!r} is a folder; expected a {what}")
        if not stat.S_ISREG(st.st_mode):
            raise ValueError(f"{str(path)!r} is not a regular file (a pipe or a device); expected a {what}")
        if st.st_size > limit:
            raise ValueError(f"{str(path)!r}: {st.st_size:,} bytes, more than the {limit:,} a {what} may have")
        chunks, size = [], 0
        while size <= limit:
            chunk = os.read(fd, min(2**20, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as e:
        raise ValueError(f"{str(path)!r}: could not read the {what} ({e.strerror or type(e).__name__})") from None
    finally:
        os.close(fd)
    if size > limit:
        raise ValueError(f"{str(path)!r}: more than the {limit:,} bytes a {what} may have")
    return b"".join(chunks)


#: The bytes :func:`file_bytes` read, by (path, inode, size, modification and change time, limit): the 64 latest.
_READS: dict[tuple, bytes] = {}


def file_bytes(path, limit: int = MAX_READ, what: str = "file") -> bytes:
    """:func:`read_bounded`, read from disk once while the file is unchanged (its hash, its check and its
    load share the bytes).

    Unchanged means the same inode, size, modification and change time: a copy that keeps the
    modification time (``cp -p``) still changes the change time, which no user can set back."""
    try:
        st = Path(path).stat()
    except OSError:
        return read_bounded(path, limit, what)  # its one clear error
    key = (str(Path(path).resolve()), st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns, limit)
    if key not in _READS:
        data = read_bounded(key[0], limit, what)
        if len(_READS) >= 64:
            _READS.pop(next(iter(_READS)))
        _READS[key] = data
    return _READS[key]


def sha256(path, limit: int = MAX_READ, what: str = "file") -> str:
    """The SHA-256 of a file's bytes (hex), as :func:`file_bytes` reads them."""
    return hashlib.sha256(file_bytes(path, limit, what)).hexdigest()
