"""Result folders: a folder holds the files of exactly one complete run.

Protocol (docs/errors.md, "Result folders"), for ``--out OUT`` = ``PARENT/NAME``:

1. **Lock.** ``PARENT/.NAME.qsma-lock`` is opened and locked with ``flock``
   (exclusive, non-blocking) for the whole run, before anything is computed. A
   second run on the same folder is refused (:class:`OutputFolderBusy`, naming the
   owner's pid). The kernel releases the lock when its owner dies, even by SIGKILL,
   so a lock is never stale.
2. **Stage.** Every file is written into a private folder
   ``PARENT/.NAME.qsma-new-RUNID``; nobody else writes there.
3. **Manifest.** ``manifest.json`` (run id, qsma version, every file with its size
   and SHA-256) is written last, after every file is flushed to disk.
4. **Swap.** The staging folder and ``OUT`` are exchanged in one system call
   (``renameat2(RENAME_EXCHANGE)``, Linux >= 3.15); the previous run, now under the
   staging name, is deleted. Without that call: ``OUT`` is renamed aside, the
   staging folder renamed to ``OUT``; a kill between the two renames is repaired by
   the next run (step 5).
5. **Clean.** Holding the lock proves that no other run is alive for ``OUT``: the
   leftovers of killed runs (``.NAME.qsma-new-*``, ``.NAME.qsma-old-*``) are deleted
   by the next run, never those of a live one.

A reader checks a folder with :func:`verify_run_folder`. At every moment ``OUT``
holds the previous complete run, the new complete run, or (first run killed) nothing.

Every command writes through this protocol (docs/errors.md, "Result folders"): a
result folder's manifest says which command wrote it (``kind``, :data:`KINDS`) and
lists every file below it, sub-folders included (``qsma run --modes`` writes
``mode-K/`` and ``qsma fit`` writes ``best/`` into its staging folder, each with a
manifest of its own: :meth:`RunFolder.subfolder`). A parameter study fills its folder
over time, so it is not staged: :class:`StudyFolder` locks it for the whole command,
removes its manifest while it changes and writes it when the study is complete.
Refused before anything is computed: a folder of another kind, files qsma did not
write, and a folder inside another result folder (it would change that folder's
files behind its manifest).
"""
from __future__ import annotations

import errno
import fcntl
import json
import os
import shutil
import signal
import socket
import threading
import time
import uuid
from contextlib import contextmanager
from pathlib import Path

from .._infra.files import (TMP_PREFIX, atomic_path, atomic_write, digest as _digest,  # noqa: F401
                           exchange as _exchange, fsync_dir as _fsync_dir,
                           replace_atomically, umask_bits as _umask_bits)
from ..errors import InputError, OutputFolderBusy, OutputWriteError
from ..version import __version__

MANIFEST = "manifest.json"
MANIFEST_VERSION = 1
#: What wrote a result folder (``kind`` of its manifest; none: a run) and how messages
#: name it.
KINDS = {"run": "qsma run", "run-modes": "qsma run --modes", "modes": "qsma modes",
         "fit": "qsma fit", "study": "qsma sweep"}
#: files qsma 0.1 wrote before manifests existed: a folder holding only these (and
#: temporary files) is an old qsma result folder and may be replaced
LEGACY_FILES = frozenset({"results.json", "results.csv", "fields.vtu", "backbone.png",
                          "loops.png", "damping_frequency.png", "interface.png",
                          "interface_map.png"})
#: errno values of a full device or an exhausted quota (write(2), close(2), fsync(2))
FULL_DEVICE = frozenset({errno.ENOSPC, errno.EDQUOT})


def check_out_path(out) -> Path:
    """``out`` as an absolute path with symbolic links resolved; refuses an empty
    name, a NUL character and anything that is not a path."""
    if not isinstance(out, (str, os.PathLike)):
        raise InputError(f"output folder must be a path, got {out!r}")
    text = os.fspath(out)
    if isinstance(text, bytes):
        text = os.fsdecode(text)
    if not text.strip():
        raise InputError("output folder is empty (--out ''); name a folder, e.g. --out results")
    if "\x00" in text:
        raise InputError(f"output folder {text!r} contains a NUL character; "
                         f"remove it from --out")
    if os.path.islink(text) and not os.path.exists(text):
        raise InputError(f"output folder {text!r} is a symbolic link that leads nowhere "
                         f"(a loop of links, or a missing target); remove the link or "
                         f"choose another --out")
    path = Path(os.path.realpath(text))
    if path.parent == path:
        raise InputError(f"output folder {text!r} is the file-system root; a run replaces "
                         f"its folder as a whole: choose a folder of its own")
    return path


def refuse_nested(path: Path):
    """Refuse a result folder inside another one: its files would change that folder
    behind its manifest (which then fails :func:`verify_run_folder`, and every later
    run into it is refused)."""
    for above in path.parents:
        if (above / MANIFEST).is_file():
            raise InputError(f"output folder {str(path)!r} lies inside {str(above)!r}, the "
                             f"result folder of a qsma command (it holds {MANIFEST}); a "
                             f"result folder holds one result: choose a folder outside it")


def prepare_output_dir(out) -> Path:
    """Check before computing that a run can be written to ``out`` (and create its
    parent folder); returns ``out`` as :func:`check_out_path` gives it.

    Nothing in ``out`` is touched: :class:`RunFolder` writes the run. Raises
    :class:`InputError` if the parent folder cannot be written, ``out`` is not a
    folder, holds files that are not from a qsma run, or is in use by another run.
    """
    with RunFolder(out) as folder:
        return folder.path


def _sidecar(out: Path, kind: str, run_id: str = "") -> Path:
    return out.parent / f".{out.name}.qsma-{kind}{'-' + run_id if run_id else ''}"



#: The lock files' descriptors this process holds. A forked child (the -alpha ramp,
#: a loop worker, the plot worker) closes its copies at once: a flock belongs to the
#: open file, so a child still running after its parent was killed would otherwise
#: hold the output folder locked until it ends.
_HELD: set = set()


def _close_held_locks():
    for fd in list(_HELD):
        try:
            os.close(fd)
        except OSError:
            pass
    _HELD.clear()


os.register_at_fork(after_in_child=_close_held_locks)

class RunFolder:
    """The result folder of one run (see the module docstring for the protocol).

    Use as a context manager::

        with RunFolder("out") as folder:     # locked; refused if another run holds it
            write files into folder.staging
            folder.commit()                  # manifest, then swap into place

    Leaving the block without :meth:`commit` (error, Ctrl-C) deletes the staging
    folder and leaves ``out`` as it was.

    Parameters
    ----------
    out : path of the result folder (created at commit; its parent is created now)
    kind : what the folder holds (:data:`KINDS`); a folder of another kind is refused
    """

    def __init__(self, out, kind="run"):
        if kind not in KINDS:
            raise ValueError(f"unknown result folder kind {kind!r}; valid: {sorted(KINDS)}")
        self.path = check_out_path(out)
        self.kind = kind
        self.run_id = f"{time.strftime('%Y%m%dT%H%M%SZ', time.gmtime())}-{uuid.uuid4().hex[:8]}"
        self.staging = _sidecar(self.path, "new", self.run_id)
        self.lock_path = _sidecar(self.path, "lock")
        self.committed = False
        self._lock_fd = None

    # -- life cycle -------------------------------------------------------------------
    def __enter__(self):
        _take_lock(self)
        try:
            self._recover()
            self._check_replaceable()
            os.mkdir(self.staging, 0o700)
        except BaseException as exc:        # also Ctrl-C / SIGTERM: leave nothing behind
            shutil.rmtree(self.staging, ignore_errors=True)
            _release(self, exc)
        return self

    def __exit__(self, *exc):
        try:
            if not self.committed:
                shutil.rmtree(self.staging, ignore_errors=True)
        finally:
            self._unlock()
        return False

    def _unwritable(self, exc):
        return InputError(f"output folder {str(self.path)!r} cannot be written "
                          f"({exc.strerror or exc}); choose another --out folder or fix "
                          f"the permissions of {str(self.path.parent)!r}")

    # -- lock ---------------------------------------------------------------------------
    def _lock(self):
        """Take the flock on the lock file; the file is verified to be the one at
        ``lock_path`` (a finishing run unlinks it while holding the lock)."""
        for _ in range(100):
            fd = os.open(self.lock_path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                owner = _wait_for_owner(fd)
                os.close(fd)
                raise OutputFolderBusy(
                    f"output folder {str(self.path)!r} is in use by another qsma run "
                    f"({owner}); wait for it to finish or choose another --out folder")
            except BaseException:
                os.close(fd)
                raise
            self._lock_fd = fd
            try:
                same = os.fstat(fd).st_ino == os.stat(self.lock_path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                info = json.dumps({"pid": os.getpid(), "host": socket.gethostname(),
                                   "run_id": self.run_id}).encode()
                os.ftruncate(fd, 0)
                os.pwrite(fd, info, 0)
                _HELD.add(fd)
                return
            self._lock_fd = None
            os.close(fd)                # lock file replaced under us: take the new one
        raise OSError(errno.EAGAIN, "could not take the lock file")

    def _unlock(self):
        if self._lock_fd is None:
            return
        try:                            # unlinked while held, and only if it is ours
            if os.stat(self.lock_path).st_ino == os.fstat(self._lock_fd).st_ino:
                os.unlink(self.lock_path)
        except OSError:
            pass
        _HELD.discard(self._lock_fd)
        os.close(self._lock_fd)
        self._lock_fd = None

    # -- recovery and checks ----------------------------------------------------------
    def _leftovers(self):
        parent, stem = self.path.parent, f".{self.path.name}.qsma-"
        return sorted(p for p in parent.iterdir()
                      if p.name.startswith(stem + "new-") or p.name.startswith(stem + "old-"))

    def _recover(self):
        """Under the lock every leftover belongs to a dead run. If ``out`` is missing
        because a run died between the two renames of the fallback swap, the newest
        complete leftover becomes ``out``; the rest is deleted."""
        leftovers = self._leftovers()
        if not self.path.exists():
            complete = [p for p in leftovers if _is_complete(p)]
            if complete:
                best = max(complete, key=lambda p: _read_manifest(p)["run_id"])
                os.rename(best, self.path)
                leftovers.remove(best)
        for p in leftovers:
            shutil.rmtree(p, ignore_errors=True)

    def _check_replaceable(self):
        """``out`` is replaced as a whole: refuse a folder with files qsma did not write,
        and one that another kind of command wrote."""
        if not self.path.exists():
            return
        if not self.path.is_dir():
            raise InputError(f"output folder {str(self.path)!r} exists and is not a folder; "
                             f"choose another --out")
        try:
            manifest = _read_manifest(self.path)
            ours = {name.split("/")[0] for name in manifest["files"]} | {MANIFEST}
        except (OSError, ValueError, KeyError, TypeError):
            manifest, ours = None, LEGACY_FILES
        if manifest is not None:
            _check_kind(self.path, manifest, self.kind)
        foreign = sorted(p.name for p in self.path.iterdir()
                         if p.name not in ours and not p.name.startswith(TMP_PREFIX))
        if foreign:
            raise InputError(
                f"output folder {str(self.path)!r} holds {len(foreign)} file(s) that are not "
                f"from a qsma run (e.g. {foreign[0]!r}); a run replaces its folder as a "
                f"whole, so choose a new or empty --out folder")

    def subfolder(self, name: str, kind: str = "run") -> "SubFolder":
        """A result folder ``name`` inside this one, written in its staging folder and
        swapped into place with it (e.g. ``mode-0`` of ``qsma run --modes``)."""
        return SubFolder(self, name, kind)

    # -- commit -------------------------------------------------------------------------
    def commit(self) -> dict:
        """Write the manifest (last), then swap the staging folder into place.

        Returns the manifest. Raises :class:`OutputWriteError` on a full device or
        another write failure; ``out`` then still holds the previous run.
        """
        try:
            manifest = _write_manifest(self.staging, self.run_id, self.kind)
            mode = (self.path.stat().st_mode & 0o7777 if self.path.is_dir()
                    else 0o777 & ~_umask_bits())
            os.chmod(self.staging, mode)
            self._swap()
        except OSError as exc:
            raise write_error(exc, self.path) from exc
        self.committed = True
        return manifest

    def _swap(self):
        if not self.path.exists():
            os.rename(self.staging, self.path)
        elif _exchange(self.staging, self.path):
            shutil.rmtree(self.staging, ignore_errors=True)     # now the previous run
        else:
            old = _sidecar(self.path, "old", self.run_id)
            with _signals_deferred():       # SIGTERM cannot split the two renames
                os.rename(self.path, old)
                os.rename(self.staging, self.path)
            shutil.rmtree(old, ignore_errors=True)
        _fsync_dir(self.path.parent)


class SubFolder:
    """A result folder inside the staging folder of a :class:`RunFolder` (``parent``):
    written like a run folder, its manifest written by :meth:`commit`, and moved into
    place when the parent is. Offers what :func:`qsma.output.files.write_all` uses of a
    :class:`RunFolder` (``path``, ``staging``, ``commit``)."""

    def __init__(self, parent: RunFolder, name: str, kind: str = "run"):
        if not name or "/" in name or name.startswith(".") or name == MANIFEST:
            raise ValueError(f"a sub-folder needs a plain name, got {name!r}")
        self.path = parent.path / name
        self.staging = parent.staging / name
        self.kind = kind
        self.run_id = parent.run_id
        self.staging.mkdir(0o755)

    def commit(self) -> dict:
        try:
            return _write_manifest(self.staging, self.run_id, self.kind)
        except OSError as exc:
            raise write_error(exc, self.path) from exc


class StudyFolder:
    """The folder of a command that fills it over time (``qsma sweep``: case folders,
    each a :class:`RunFolder` of its own, written as they finish; a resumed study adds
    to it). It cannot be swapped in one step, so:

    - it is locked for the whole command (as a :class:`RunFolder`: a second study on it
      is refused, naming the owner), before anything is computed;
    - refused if it lies inside another result folder, holds another kind of result,
      or holds a file for which ``allowed(name)`` is false;
    - its manifest is removed before the first file changes (:meth:`changing`:
      :func:`verify_run_folder` then says it is not complete) and written by
      :meth:`commit`, listing every file below it, once the study is complete.
    """

    def __init__(self, out, allowed, kind="study"):
        self.path = check_out_path(out)
        self.kind, self.allowed = kind, allowed
        self.run_id = f"{time.strftime('%Y%m%dT%H%M%SZ', time.gmtime())}-{uuid.uuid4().hex[:8]}"
        self.lock_path = _sidecar(self.path, "lock")
        self._lock_fd = None

    _lock = RunFolder._lock
    _unlock = RunFolder._unlock
    _unwritable = RunFolder._unwritable

    def __enter__(self):
        _take_lock(self)
        try:
            self._check()
            self.path.mkdir(exist_ok=True)
        except BaseException as exc:
            _release(self, exc)
        return self

    def __exit__(self, *exc):
        self._unlock()
        return False

    def _check(self):
        if not self.path.exists():
            return
        if not self.path.is_dir():
            raise InputError(f"output folder {str(self.path)!r} exists and is not a folder; "
                             f"choose another --out")
        try:
            manifest = _read_manifest(self.path)
        except (OSError, ValueError, KeyError, TypeError):
            manifest = None
        if manifest is not None:
            _check_kind(self.path, manifest, self.kind)
        foreign = sorted(p.name for p in self.path.iterdir()
                         if p.name != MANIFEST and not p.name.startswith(".")
                         and not self.allowed(p.name))
        if foreign:
            raise InputError(
                f"output folder {str(self.path)!r} holds {len(foreign)} file(s) that are "
                f"not from a {KINDS[self.kind]} (e.g. {foreign[0]!r}); choose a new or "
                f"empty --out folder, or that of the same study to resume it")

    def changing(self):
        """Remove the manifest: the folder is about to change (before the first file is
        written; a command refused after entering leaves the folder as it was)."""
        (self.path / MANIFEST).unlink(missing_ok=True)

    def commit(self) -> dict:
        """Write the manifest of the complete folder (every file below it). Leftovers
        of killed case runs are deleted first: the lock proves no run of this study
        is alive."""
        for p in self.path.iterdir():
            if p.name.startswith(".") and (".qsma-new-" in p.name or ".qsma-old-" in p.name):
                shutil.rmtree(p, ignore_errors=True)
        try:
            return _write_manifest(self.path, self.run_id, self.kind)
        except OSError as exc:
            raise write_error(exc, self.path) from exc


def _check_kind(path: Path, manifest: dict, kind: str):
    """Refuse to write a result of ``kind`` into a folder another kind of command wrote."""
    theirs = manifest.get("kind", "run")
    if theirs != kind:
        raise InputError(f"output folder {str(path)!r} holds the result of "
                         f"{KINDS.get(theirs, theirs)}, not of {KINDS[kind]}; choose another "
                         f"--out folder (or delete that one)")


def _tree(folder: Path) -> list:
    """Relative POSIX paths of the files below ``folder``, sorted; the top manifest, the
    lock files of sub-folders and temporary files left out."""
    out = []
    for root, dirs, files in os.walk(folder):
        dirs.sort()
        rel = Path(root).relative_to(folder)
        for name in sorted(files):
            if name.startswith(TMP_PREFIX) or (name.startswith(".") and ".qsma-lock" in name):
                continue
            path = (rel / name).as_posix()
            if path != MANIFEST:
                out.append(path)
    return out


def _write_manifest(folder: Path, run_id: str, kind: str) -> dict:
    """Write ``folder``'s manifest last, after every file below it is flushed to disk:
    run id, qsma version, kind, and each file with its size and SHA-256. Temporary files
    left in a private staging folder are deleted."""
    for root, _, names in os.walk(folder):
        for name in names:
            if name.startswith(TMP_PREFIX):
                os.unlink(os.path.join(root, name))
    files = {name: _digest(folder / name) for name in _tree(folder)}
    manifest = {"qsma_manifest": MANIFEST_VERSION, "run_id": run_id, "kind": kind,
                "qsma_version": __version__, "complete": True,
                "written_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                "files": files}
    with open(folder / MANIFEST, "w") as f:
        f.write(json.dumps(manifest, indent=1) + "\n")
        f.flush()
        os.fsync(f.fileno())
    for root, _, _ in os.walk(folder):
        _fsync_dir(root)
    return manifest


@contextmanager
def _signals_deferred():
    """SIGINT and SIGTERM that arrive inside the block are delivered after it, to the
    handlers in place before (so a handler raising ``KeyboardInterrupt`` finds a
    consistent state). A signal mask would not do: the kernel hands a blocked signal
    to another thread (BLAS), and Python runs the handler in the main thread anyway."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []
    held = (signal.SIGINT, signal.SIGTERM)
    previous = {s: signal.signal(s, lambda signum, frame: caught.append(signum))
                for s in held}
    try:
        yield
    finally:
        for s, handler in previous.items():   # None: set outside Python, default then
            signal.signal(s, signal.SIG_DFL if handler is None else handler)
        for signum in caught:
            signal.raise_signal(signum)


def write_error(exc: OSError, out) -> OutputWriteError:
    """The :class:`OutputWriteError` for an ``OSError`` raised while writing results."""
    what = "the device is full" if exc.errno in FULL_DEVICE else (exc.strerror or str(exc))
    fix = ("free space on that device" if exc.errno in FULL_DEVICE
           else "check the device and its permissions")
    name = f" ({Path(exc.filename).name})" if getattr(exc, "filename", None) else ""
    return OutputWriteError(f"cannot write the results into {str(out)!r}: {what}{name}; "
                            f"the folder still holds its previous contents. Fix: {fix} "
                            f"or choose another --out folder")


def verify_run_folder(out) -> dict:
    """Check that ``out`` holds one complete run; returns its manifest.

    Raises :class:`InputError` when the manifest is missing or unreadable, a listed
    file is missing or differs from its recorded size or SHA-256, or the folder
    holds a file the manifest does not list.
    """
    out = Path(out)
    try:
        manifest = _read_manifest(out)
        listed = manifest["files"]
    except FileNotFoundError:
        raise InputError(f"{str(out)!r} holds no {MANIFEST}: not a complete qsma run "
                         f"(interrupted, or written by qsma < 0.2)") from None
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise InputError(f"{str(out / MANIFEST)!r} cannot be read: {exc}") from exc
    present = set(_tree(out))
    if present != set(listed):
        raise InputError(f"{str(out)!r}: files {sorted(present ^ set(listed))} differ from "
                         f"those of run {manifest['run_id']} in its {MANIFEST}")
    for name, rec in listed.items():
        if _digest(out / name, sync=False) != rec:
            raise InputError(f"{str(out / name)!r} differs from the SHA-256 recorded in "
                             f"{MANIFEST} (run {manifest['run_id']}): the folder was "
                             f"changed after the run")
    return manifest


def _read_manifest(folder: Path) -> dict:
    data = json.loads((Path(folder) / MANIFEST).read_text(encoding="utf-8"))
    if not (isinstance(data, dict) and data.get("complete") is True
            and isinstance(data.get("files"), dict)):
        raise ValueError(f"{MANIFEST} is not a complete qsma manifest")
    return data


def _is_complete(folder: Path) -> bool:
    try:
        verify_run_folder(folder)
        return True
    except (InputError, OSError):
        return False


def _wait_for_owner(fd, tries=40, pause_s=0.005) -> str:
    """The lock owner's description; a run that has just taken the lock writes it
    right after (``_lock``), so an empty file is read again for up to 0.2 s before the
    owner is called unknown (two runs started at the same moment)."""
    for _ in range(tries - 1):
        owner = _read_owner(fd)
        if owner != UNKNOWN_OWNER:
            return owner
        time.sleep(pause_s)
    return _read_owner(fd)


UNKNOWN_OWNER = "owner unknown"


def _read_owner(fd) -> str:
    try:
        info = json.loads(os.pread(fd, 4096, 0).decode())
        return f"pid {info['pid']} on {info['host']}, run {info['run_id']}"
    except (OSError, ValueError, KeyError, TypeError):
        return UNKNOWN_OWNER


def _take_lock(folder):
    """Take the lock of a run or study folder: refused inside another result folder
    (before a parent is created inside one), the parent made, the lock file never left
    half-taken (signals deferred); an unwritable place named with its fix."""
    refuse_nested(folder.path)
    try:
        folder.path.parent.mkdir(parents=True, exist_ok=True)
        with _signals_deferred():
            folder._lock()
    except BaseException as exc:
        _release(folder, exc)


def _release(folder, exc):
    """Give up the lock of ``folder`` after ``exc`` and raise it again; an OSError as
    the folder's unwritable-place error naming the fix."""
    folder._unlock()
    if isinstance(exc, OSError):
        raise folder._unwritable(exc) from exc
    raise exc
