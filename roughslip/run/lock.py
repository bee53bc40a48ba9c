"""One writer per run file: an exclusive lock, held for the whole run.

A run takes the lock before it touches its output in any way (a new file, ``--overwrite``,
``--resume``, the journal) and keeps it until its last act, on every way out: the end, an
error, Ctrl-C, SIGTERM and SIGHUP. A second run on the same file, with or without
``--overwrite`` or ``--resume``, is refused at once with one line that names the file and the
run holding it (:class:`~roughslip.errors.OutputBusyError`, exit code 2); without the lock it
would remove the journal from under the first one, and samples would be lost while both said
they had computed them.

The lock is ``flock(LOCK_EX)`` on ``OUT.h5.lock`` beside the output. The file holds the
holder's PID, host and start time for the message; the lock itself is the kernel's, released
when the holder's process ends however it ends (``kill -9`` too), so a lock file left by a
killed run blocks nothing and is taken over by the next run. A run removes its lock file at
its end while it still holds the lock; a run that was waiting on the removed file finds it
gone (or replaced) after locking it and locks the new one instead, so two runs never hold
locks on two different files of the same name.

What is promised where:

* Local file systems: a second run on the same machine is refused.
* NFS: Linux implements ``flock`` on NFS with the protocol's byte-range locks (NFSv4, or NFSv3
  with the lock manager running), so runs on different hosts exclude each other too. After a
  crash of the holder's machine the server releases its lock when the machine's lease ends
  (about 90 s on NFSv4 by default).
* Mounts that lock locally only (NFS with ``nolock`` or ``local_lock=flock``, Lustre with
  ``localflock``, some FUSE and SMB file systems): only runs on the same host are refused;
  runs on two hosts are not, and must not share an output.
* File systems that refuse locks (``ENOLCK``, ``EOPNOTSUPP``, ``ENOSYS``): the run goes on
  without the lock and says so in a note.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import socket
import time
from collections.abc import Iterator
from pathlib import Path

from roughslip.errors import OutputBusyError, io_cause, io_failure

try:
    import fcntl
except ImportError:  # a platform without flock: runs go on unlocked, with a note
    fcntl = None

#: the errors of a file system that has no locks at all
_NO_LOCKS = {errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOTSUP, errno.ENOSYS}
#: how long a refused run waits for the holder to write its name (it does so at once after
#: locking; the wait only covers that instant)
_NAME_WAIT = 1.0


def lock_path(path: str | Path) -> Path:
    """The lock file of a run file: ``OUT.h5.lock``."""
    path = Path(path)
    return path.with_name(path.name + ".lock")


class RunLock:
    """The lock of one run file, held from :meth:`acquire` until :meth:`release`.

    Attributes
    ----------
    path : Path
        The run file.
    note : str
        Empty, or why the run holds no lock (a file system without locks), for the user.
    """

    def __init__(self, path: Path, fd: int, note: str = "") -> None:
        self.path = path
        self.file = lock_path(path)
        self.note = note
        self._fd: int | None = fd

    @classmethod
    def acquire(cls, path: str | Path) -> RunLock:
        """Lock the run file ``path`` for this process, or refuse at once.

        Parameters
        ----------
        path : path
            The run file (it need not exist; its folder is made when missing).

        Returns
        -------
        RunLock

        Raises
        ------
        OutputBusyError
            When another run holds the lock; the message names the file and the holder's PID
            and host.
        OutputError
            When the lock file cannot be made (a folder that cannot be written).
        """
        path = Path(path)
        file = lock_path(path)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise io_failure(path, "cannot make its folder", exc) from exc
        while True:
            try:
                fd = os.open(file, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
            except OSError as exc:
                raise io_failure(path, f"cannot create the lock file {file.name}",
                                 exc) from exc
            try:
                if fcntl is None:
                    raise OSError(errno.ENOSYS, "this platform has no flock")
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _holder(fd)
                os.close(fd)
                raise OutputBusyError(f"{path}: another run is writing this file ({holder}; "
                                      f"lock file {file}); wait for it to end, or write to "
                                      "another file") from None
            except OSError as exc:
                if exc.errno not in _NO_LOCKS:
                    os.close(fd)
                    raise io_failure(path, f"cannot lock {file.name}", exc) from exc
                lock = cls(path, fd, note=f"{file}: the file system does not lock files "
                                          f"({io_cause(exc)}); a second run on {path.name} "
                                          "would not be refused")
                lock._sign()
                return lock
            if _same_file(fd, file):
                lock = cls(path, fd)
                lock._sign()
                return lock
            os.close(fd)  # the holder ended and removed the file we locked: lock the new one

    def _sign(self) -> None:
        """Write this process's PID, host and start time into the lock file."""
        if self._fd is None:
            return
        text = json.dumps({"pid": os.getpid(), "host": socket.gethostname(),
                           "since": time.strftime("%Y-%m-%d %H:%M:%S")}) + "\n"
        try:
            os.ftruncate(self._fd, 0)
            os.pwrite(self._fd, text.encode(), 0)
        except OSError:
            pass  # only information: the lock holds without it

    def release(self) -> None:
        """Remove the lock file, then unlock (a second call does nothing)."""
        if self._fd is None:
            return
        fd, self._fd = self._fd, None
        try:
            if _same_file(fd, self.file):
                self.file.unlink()
        except OSError:
            pass  # the folder is gone or not writable: the lock ends with the descriptor
        finally:
            os.close(fd)


@contextlib.contextmanager
def holding(path: str | Path) -> Iterator[RunLock]:
    """Hold the lock of the run file ``path`` inside the block (:meth:`RunLock.acquire`),
    and release it on every way out of it.

    Parameters
    ----------
    path : path
        The run file.

    Yields
    ------
    RunLock
    """
    lock = RunLock.acquire(path)
    try:
        yield lock
    finally:
        lock.release()


def _same_file(fd: int, file: Path) -> bool:
    """Whether ``file`` still names the file open as ``fd``."""
    try:
        st = os.stat(file)
    except OSError:
        return False
    fs = os.fstat(fd)
    return (st.st_dev, st.st_ino) == (fs.st_dev, fs.st_ino)


def _may_hold(info: dict) -> bool:
    """False when the lock file names a process of this host that has ended: what a killed
    run left, not yet overwritten by the run that holds the lock now."""
    if info.get("host") != socket.gethostname():
        return True
    try:
        os.kill(int(info["pid"]), 0)
    except ProcessLookupError:
        return False
    except (OSError, ValueError):
        pass
    return True


def _holder(fd: int) -> str:
    """Who holds the lock, from its file: "PID 123 on host, since ...". The holder writes it
    right after locking; a reader that comes in that instant (finding the file empty, or
    still naming a run that was killed) waits for it, briefly."""
    deadline = time.monotonic() + _NAME_WAIT
    while True:
        try:
            info = json.loads(os.pread(fd, 4096, 0).decode() or "null")
            if isinstance(info, dict) and "pid" in info and _may_hold(info):
                return (f"PID {info['pid']} on {info.get('host', '?')}, since "
                        f"{info.get('since', '?')}")
        except (OSError, ValueError):
            pass
        if time.monotonic() > deadline:
            return "its PID and host are not known"
        time.sleep(0.01)
