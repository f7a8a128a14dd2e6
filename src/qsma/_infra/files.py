"""Files written atomically: a reader sees the old file or the complete new one, never
half a file. Shared by the mesh writers, the result folders and their files."""
from __future__ import annotations

import ctypes
import errno
import hashlib
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

__all__ = ["TMP_PREFIX", "atomic_path", "atomic_write", "replace_atomically", "digest",
           "fsync_dir", "exchange", "umask_bits"]

#: prefix of the temporary files renamed into place by :func:`atomic_path`
TMP_PREFIX = ".qsma-tmp-"
_RENAME_EXCHANGE = 2            # linux/fs.h


def _umask_mode():
    """Permission bits of a normally created file."""
    return 0o666 & ~umask_bits()


def replace_atomically(tmp, path):
    """Give ``tmp`` the permissions of a normally created file and rename it to ``path``."""
    os.chmod(tmp, _umask_mode())
    os.replace(tmp, path)


@contextmanager
def atomic_path(path):
    """A temporary path beside ``path`` (same suffix, hidden prefix) to write to; on
    success it is renamed to ``path``, on any failure or interruption it is removed.
    Readers see either the old file or the complete new one."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f"{TMP_PREFIX}{path.stem}.", suffix=path.suffix,
                               dir=path.parent)
    os.close(fd)
    try:
        yield tmp
        replace_atomically(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def atomic_write(path, data, mode="w"):
    """Write ``data`` (str or bytes) to ``path`` atomically (:func:`atomic_path`); text as
    UTF-8 with ``\n`` line ends."""
    text = {} if "b" in mode else {"encoding": "utf-8", "newline": "\n"}
    with atomic_path(path) as tmp, open(tmp, mode, **text) as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())


def digest(path: Path, sync=True) -> dict:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
        if sync:
            os.fsync(f.fileno())
        size = f.tell()
    return {"bytes": size, "sha256": h.hexdigest()}


def umask_bits():
    """The process umask (read by setting and restoring it)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def fsync_dir(path):
    fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def exchange(a: Path, b: Path) -> bool:
    """Atomically exchange two paths (Linux ``renameat2(RENAME_EXCHANGE)``); ``False``
    where the system or the file system does not offer it."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd = -100                                 # fcntl.h
    rc = renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), _RENAME_EXCHANGE)
    if rc == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP):
        return False
    raise OSError(err, os.strerror(err), str(b))
