"""CPU-heavy work in a child process with a time limit (imports, coverage planning).

Why a process and not a thread: a thread holding the GIL slows every other
request of the server, and a thread cannot be stopped, so an abusive request
could keep a core busy for minutes and SIGTERM could not end the server. A
child is forked from a ``forkserver`` that has the heavy modules (numpy,
shapely, pyproj, the planner) imported once, so a fork costs milliseconds; on
time-out the child is killed (its database connection drops, so PostgreSQL
rolls its transaction back) and the caller gets ``TooExpensive``.

At most ``FIELDRX_HEAVY_WORKERS`` children run at once per server process;
further requests wait up to their own time limit for a slot, then get ``Busy``
(503).

A child dies with its caller (``watch_caller``: the kernel's parent-death signal and a
thread watching the caller), and before committing it checks that the caller is still
there (``ensure_caller_alive``), so nothing is committed for a client that has gone.

A background task (``fieldrx.tasks``) passes ``should_stop``: polled about once a second
while the child works, and when it says so the child is killed (its transaction rolls
back) and ``Cancelled`` is raised, so a cancelled plan stops within a second even in a
stage that reports no progress.
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import multiprocessing.util
import os
import pickle
import signal
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from multiprocessing.connection import Connection
from typing import Any, TypeVar

from fieldrx.errors import Busy, Cancelled, TooExpensive
from fieldrx.proctag import process_tag, tag_alive
from fieldrx.settings import get_settings

T = TypeVar("T")

_PRELOAD = [
    "numpy",
    "shapely",
    "pyproj",
    "sqlalchemy",
    "psycopg",
    "fieldrx.db.models",
    "fieldrx.services.plans",
    "fieldrx.agronomy.soil",
    "fieldrx.formats.field_import",
    "fieldrx.geo.validate",
    "fieldrx.tasks.work",
]
_ctx = multiprocessing.get_context("forkserver")
_ctx.set_forkserver_preload(_PRELOAD)
_slots: threading.BoundedSemaphore | None = None
_slots_lock = threading.Lock()


def get_slots() -> threading.BoundedSemaphore:
    global _slots
    with _slots_lock:
        if _slots is None:
            _slots = threading.BoundedSemaphore(max(1, get_settings().heavy_workers))
        return _slots


# The forkserver listens on a Unix socket in multiprocessing's temporary directory,
# ``$TMPDIR/pymp-XXXXXXXX/listener-XXXXXXXX``, and a socket path holds at most 107 bytes
# (``sun_path``). Under a long TMPDIR (a CI job's or a container's own directory) every
# heavy request would fail on "AF_UNIX path too long". Python 3.13 falls back to /tmp for
# that reason, 3.11 does not, so the same choice is made here before the forkserver starts.
_SOCKET_SUFFIX = len("/pymp-XXXXXXXX/listener-XXXXXXXX")
_SUN_PATH_MAX = 107
_SHORT_TMP = ("/tmp", "/var/tmp", "/dev/shm")
_socket_dir_lock = threading.Lock()
_socket_dir_done = False


def _fits(directory: str) -> bool:
    return len(os.fsencode(directory)) + _SOCKET_SUFFIX <= _SUN_PATH_MAX


def socket_dir_fits() -> None:
    """Make multiprocessing keep its sockets in a directory short enough for a socket
    path (the first writable of /tmp, /var/tmp, /dev/shm when TMPDIR is too long); other
    temporary files (spooled uploads) stay under TMPDIR. Idempotent."""
    global _socket_dir_done
    with _socket_dir_lock:
        if _socket_dir_done:
            return
        _socket_dir_done = True
        base = tempfile.gettempdir()  # also fixes tempfile.tempdir for the restore below
        if _fits(base):
            return
        short = next(
            (d for d in _SHORT_TMP if _fits(d) and os.access(d, os.W_OK | os.X_OK)), None
        )
        if short is None:
            return  # nothing shorter to use: the forkserver's own error will say why
        tempfile.tempdir = short
        try:
            multiprocessing.util.get_temp_dir()  # created now, kept for the process
        finally:
            tempfile.tempdir = base


def warm_up() -> None:
    """Start the forkserver (importing the heavy modules) in the background, so the first
    heavy request does not pay for it while other requests are waiting."""
    from multiprocessing import forkserver

    socket_dir_fits()
    threading.Thread(
        target=forkserver.ensure_running, name="forkserver-warm-up", daemon=True
    ).start()


PR_SET_PDEATHSIG = 1  # linux/prctl.h
WATCH_S = 0.2  # how often a child checks that its caller is still there
_caller_tag: str | None = None  # set in a child: the process that waits for its answer


def die_with_parent() -> None:
    """Ask the kernel to SIGKILL this process when its parent dies (Linux; elsewhere a
    no-op)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):
        return


def watch_caller(caller_tag: str) -> None:
    """Make this child die with the process that started it and waits for it.

    Two mechanisms: the kernel's parent-death signal (immediate, but the parent of a
    forkserver child is the forkserver, which stays alive as long as any child holds its
    "alive" pipe, as every child does), and a thread that checks the caller's tag
    (``fieldrx.proctag``) every ``WATCH_S`` and kills this process once it is gone. A
    caller that died before this ran ends the child at once."""
    global _caller_tag
    _caller_tag = caller_tag
    die_with_parent()
    if not tag_alive(caller_tag):
        os._exit(1)

    def watch() -> None:
        while tag_alive(caller_tag):
            time.sleep(WATCH_S)
        os.kill(os.getpid(), signal.SIGKILL)

    threading.Thread(target=watch, name="caller-watch", daemon=True).start()


def caller_alive() -> bool:
    """False in a child whose caller (the server or worker process) has gone."""
    return _caller_tag is None or tag_alive(_caller_tag)


def ensure_caller_alive(what: str) -> None:
    """Raise ``Cancelled`` (the caller rolls back) when the caller has gone: called right
    before a child commits, so work whose client is gone is never stored."""
    if not caller_alive():
        raise Cancelled(f"{what}: the process that asked for it has gone; nothing was stored")


def _child(
    conn: Connection, fn: Callable[..., Any], args: tuple[Any, ...], caller_tag: str
) -> None:
    watch_caller(caller_tag)
    try:
        result: tuple[bool, Any] = (True, fn(*args))
    except BaseException as exc:  # noqa: BLE001 - every failure goes back to the parent
        result = (False, exc)
    try:
        conn.send(result)
    except (pickle.PicklingError, TypeError, AttributeError) as exc:
        conn.send((False, RuntimeError(f"{type(result[1]).__name__}: {result[1]} ({exc})")))
    finally:
        conn.close()


STOP_POLL_S = 1.0


def _wait(
    recv: Connection,
    t0: float,
    time_limit_s: float,
    what: str,
    should_stop: Callable[[], bool] | None = None,
) -> None:
    """Wait for the child's answer in short steps: past the time limit, once the server's
    main thread has ended (SIGTERM after the graceful-shutdown timeout), or when
    ``should_stop()`` says so (checked every ``STOP_POLL_S``), give up."""
    next_check = time.monotonic()  # at once: a cancel may have come while the child started
    while not recv.poll(0.25):
        if should_stop is not None and time.monotonic() >= next_check:
            next_check = time.monotonic() + STOP_POLL_S
            if should_stop():
                raise Cancelled(f"{what} was cancelled; nothing was stored")
        if time.monotonic() - t0 >= time_limit_s:
            raise TooExpensive(
                f"{what} took longer than the {time_limit_s:g} s limit and was stopped; "
                "nothing was stored"
            )
        if not threading.main_thread().is_alive():
            raise Busy(f"the server is shutting down; {what} was stopped, retry it")


@contextlib.contextmanager
def heavy_slot(time_limit_s: float, what: str) -> Iterator[None]:
    """One of the ``FIELDRX_HEAVY_WORKERS`` slots of this process for the block (planning,
    imports, imagery conversions share them); ``Busy`` when none frees up in time."""
    slots = get_slots()
    if not slots.acquire(timeout=time_limit_s):
        raise Busy(f"the server is busy with other heavy requests; retry {what} later")
    try:
        yield
    finally:
        slots.release()


def run_bounded(
    fn: Callable[..., T],
    *args: Any,
    time_limit_s: float,
    what: str,
    should_stop: Callable[[], bool] | None = None,
) -> T:
    """``fn(*args)`` in a child process; its exception is re-raised here.

    ``fn`` must be a module-level function and ``args``/result picklable. Raises
    ``TooExpensive`` when the child runs past ``time_limit_s`` (the child is killed),
    ``Busy`` when no worker slot frees up within the limit, and ``Cancelled`` when
    ``should_stop()`` turns true (the child is killed).
    """
    t0 = time.monotonic()
    socket_dir_fits()
    with heavy_slot(time_limit_s, what):
        recv, send = _ctx.Pipe(duplex=False)
        proc = _ctx.Process(target=_child, args=(send, fn, args, process_tag()), daemon=True)
        proc.start()
        send.close()
        try:
            _wait(recv, t0, time_limit_s, what, should_stop)
            try:
                ok, value = recv.recv()
            except EOFError:
                proc.join(1)
                raise TooExpensive(
                    f"{what} was stopped (worker exit code {proc.exitcode}: out of memory or "
                    "killed); nothing was stored"
                ) from None
        finally:
            if proc.is_alive():
                proc.kill()
            proc.join(5)
            recv.close()
    if ok:
        return value
    raise value
