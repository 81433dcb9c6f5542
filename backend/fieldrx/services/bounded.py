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

A background task (``fieldrx.tasks``) passes ``should_stop``: polled about once a second
while the child works, and when it says so the child is killed (its transaction rolls
back) and ``Cancelled`` is raised, so a cancelled plan stops within a second even in a
stage that reports no progress.
"""

from __future__ import annotations

import multiprocessing
import pickle
import threading
import time
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any, TypeVar

from fieldrx.errors import Busy, Cancelled, TooExpensive
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


def _get_slots() -> threading.BoundedSemaphore:
    global _slots
    with _slots_lock:
        if _slots is None:
            _slots = threading.BoundedSemaphore(max(1, get_settings().heavy_workers))
        return _slots


def warm_up() -> None:
    """Start the forkserver (importing the heavy modules) in the background, so the first
    heavy request does not pay for it while other requests are waiting."""
    from multiprocessing import forkserver

    threading.Thread(
        target=forkserver.ensure_running, name="forkserver-warm-up", daemon=True
    ).start()


def _child(conn: Connection, fn: Callable[..., Any], args: tuple[Any, ...]) -> None:
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
    next_check = time.monotonic() + STOP_POLL_S
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
    slots = _get_slots()
    if not slots.acquire(timeout=time_limit_s):
        raise Busy(f"the server is busy with other heavy requests; retry {what} later")
    try:
        recv, send = _ctx.Pipe(duplex=False)
        proc = _ctx.Process(target=_child, args=(send, fn, args), daemon=True)
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
    finally:
        slots.release()
    if ok:
        return value
    raise value
