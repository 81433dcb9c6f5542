"""The acceptance test: 20 fields planned through the queue by two ``fieldrx worker``
processes, progress visible through the API while they run, one worker SIGKILLed in the
middle of a plan: every plan is stored exactly once (none missing, none duplicated).

The killed worker's job is handed on by the survivor's stalled-job recovery (heartbeat
0.5 s, stalled after 3 s here); the killed worker's planning child may still be running
(it is a child of the worker's forkserver, not of the worker) and commit its plan, which is
the case the per-task guard exists for.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import text

from tests.tasks.helpers import make_fields, wait_until

N_FIELDS = 20
PLAN = {"swath_width_m": 2.0, "cell_length_m": 2.0}  # ~30k cells per 12 ha field


class Worker:
    """``python -m fieldrx.cli worker --role tasks`` on the test database, its own session
    (so its planning children can be cleaned up with it)."""

    def __init__(self, database_url: str, log: Path) -> None:
        env = {
            **os.environ,
            "DATABASE_URL": database_url,
            "FIELDRX_TASK_HEARTBEAT_S": "0.5",
            "FIELDRX_TASK_STALLED_AFTER_S": "3",
            "FIELDRX_TASK_CONCURRENCY": "1",
        }
        self.log = log
        self.fh = open(log, "wb")  # noqa: SIM115 - closed in stop()
        self.p = subprocess.Popen(
            [sys.executable, "-m", "fieldrx.cli", "worker", "--role", "tasks"],
            env=env,
            stdout=self.fh,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )

    def name_prefix(self) -> str:
        return f":{self.p.pid}"

    def stop(self) -> int | None:
        if self.p.poll() is None:
            self.p.send_signal(signal.SIGTERM)
            try:
                self.p.wait(30)
            except subprocess.TimeoutExpired:
                self.p.kill()
                self.p.wait(5)
        try:  # leftovers of its session (a killed worker's planning child)
            os.killpg(self.p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.fh.close()
        return self.p.returncode


def _running_on(db: Any, ids: list[int], pid: int) -> list[int]:
    db.rollback()
    return [
        r[0]
        for r in db.execute(
            text(
                "SELECT id FROM tasks WHERE id = ANY(:ids) AND status = 'running' "
                "AND worker LIKE :w"
            ),
            {"ids": ids, "w": f"%:{pid}"},
        )
    ]


@pytest.mark.timeout(600)
@pytest.mark.parametrize("kill", ["worker", "worker_and_children"])
def test_twenty_plans_two_workers_one_killed(
    client, org, db, database_url, tmp_path, kill: str
) -> None:
    """``worker``: SIGKILL the worker process alone (its planning child lives on and may
    commit: the retried job must then find the plan, not store a second one);
    ``worker_and_children``: the whole process group (power loss: the other worker must
    plan it again from scratch)."""
    field_ids = make_fields(client, org, N_FIELDS, 400, 300)
    r = client.post(
        "/api/v1/plans/batch", headers=org.headers(), json={"field_ids": field_ids, "params": PLAN}
    )
    assert r.status_code == 202, r.text
    url = r.json()["url"]
    batch = client.get(url, headers=org.headers()).json()
    child_ids = [k["id"] for k in batch["items"]]
    assert len(child_ids) == N_FIELDS and batch["status"] == "queued"

    a = Worker(database_url, tmp_path / "worker-a.log")
    b = Worker(database_url, tmp_path / "worker-b.log")
    seen_batch: list[float] = []
    seen_child: list[float] = []
    killed_task: int | None = None
    try:

        def observe() -> dict[str, Any]:
            view = client.get(url, headers=org.headers()).json()
            seen_batch.append(view["progress"])
            seen_child.extend(k["progress"] for k in view["items"] if k["status"] == "running")
            return view

        def kill_moment() -> list[int] | None:
            view = observe()
            if view["counts"]["succeeded"] < 2:
                return None
            running = _running_on(db, child_ids, a.p.pid)
            return running or None

        running = wait_until(kill_moment, 240, "worker A to be planning, 2 plans done", 0.05)
        killed_task = running[0]
        if kill == "worker":
            a.p.send_signal(signal.SIGKILL)
        else:
            os.killpg(a.p.pid, signal.SIGKILL)
        a.p.wait(10)
        done_at_kill = observe()["counts"]["succeeded"]
        assert done_at_kill < N_FIELDS

        final = wait_until(
            lambda: (v := observe())["status"] in ("succeeded", "failed", "cancelled") and v,
            400,
            "the batch to finish",
            0.2,
        )
    finally:
        a_rc = a.stop()
        b_rc = b.stop()
    logs = f"--- A ---\n{a.log.read_text()[-3000:]}\n--- B ---\n{b.log.read_text()[-3000:]}"
    assert a_rc == -signal.SIGKILL
    assert b_rc == 0, logs
    failed = [(k["id"], k["error"]) for k in final["items"] if k["status"] != "succeeded"]
    assert final["status"] == "succeeded", (failed, logs)
    assert final["counts"]["succeeded"] == N_FIELDS and final["progress"] == 1.0

    # progress was visible while the workers ran: the batch between 0 and 1, and a running
    # plan between its stages
    assert any(0 < p < 1 for p in seen_batch), seen_batch[:50]
    assert any(0 < p < 1 for p in seen_child), seen_child[:50]

    # every plan exactly once: one plan per field, the one its task links to, complete
    db.rollback()
    per_field = dict(
        db.execute(
            text("SELECT field_id, count(*) FROM plans WHERE field_id = ANY(:f) GROUP BY field_id"),
            {"f": field_ids},
        ).all()
    )
    assert per_field == dict.fromkeys(field_ids, 1), per_field
    linked = {k["params"]["field_id"]: k["result"]["plan_id"] for k in final["items"]}
    stored = dict(
        db.execute(
            text("SELECT field_id, id FROM plans WHERE field_id = ANY(:f)"), {"f": field_ids}
        ).all()
    )
    assert linked == stored
    for plan_id in stored.values():
        n, cells = db.execute(
            text(
                "SELECT p.n_cells, (SELECT count(*) FROM plan_cells c WHERE c.plan_id = p.id) "
                "FROM plans p WHERE p.id = :id"
            ),
            {"id": plan_id},
        ).one()
        assert n == cells > 0

    # the killed worker's job was handed to the other worker; the task finished once: by the
    # killed worker's orphaned child (then the retry found it done) or by the other worker
    killed = db.execute(
        text(
            "SELECT t.attempts, t.status, t.worker, j.attempts AS job_attempts, "
            "j.status::text AS job_status FROM tasks t JOIN procrastinate_jobs j "
            "ON j.id = t.job_id WHERE t.id = :id"
        ),
        {"id": killed_task},
    ).one()
    assert killed.job_attempts >= 1 and killed.job_status == "succeeded", killed
    assert killed.status == "succeeded", killed
    if killed.attempts >= 2:
        how = "restarted by worker B"
        assert killed.worker.endswith(f":{b.p.pid}"), killed
    else:
        how = "finished by worker A's orphaned child, retry found it done"
        assert kill == "worker" and killed.worker.endswith(f":{a.p.pid}"), killed
    jobs = db.execute(
        text(
            "SELECT j.status::text, count(*) FROM procrastinate_jobs j JOIN tasks t "
            "ON t.job_id = j.id WHERE t.id = ANY(:ids) GROUP BY 1"
        ),
        {"ids": child_ids},
    ).all()
    assert dict(jobs) == {"succeeded": N_FIELDS}, jobs
    workers = db.execute(
        text("SELECT worker, count(*) FROM tasks WHERE id = ANY(:ids) GROUP BY 1"),
        {"ids": child_ids},
    ).all()
    print(
        f"\nqueue acceptance: {N_FIELDS} plans, {done_at_kill} done when worker A "
        f"(pid {a.p.pid}, kill={kill}) was killed in task {killed_task} ({how}); "
        f"plans per worker {dict(workers)}"
    )


@pytest.mark.timeout(600)
def test_cancel_of_a_running_plan_stops_it_within_seconds(
    client, org, db, database_url, tmp_path
) -> None:
    """A plan of ~1 million cells runs in a real ``fieldrx worker``; the API's cancel
    route is called once it reports progress: the task is cancelled (its status says so)
    and no database session of its work is left running, within a couple of seconds."""
    import time

    (fid,) = make_fields(client, org, 1, 1500, 1000)
    task = client.post(
        f"/api/v1/fields/{fid}/plans?background=true",
        headers=org.headers(),
        json={"swath_width_m": 1.5, "cell_length_m": 1.0},
    ).json()
    w = Worker(database_url, tmp_path / "worker.log")
    try:
        wait_until(
            lambda: client.get(task["url"], headers=org.headers()).json()["progress"] > 0,
            300,
            "the plan to report progress in the worker",
            step_s=0.05,
        )
        t0 = time.monotonic()
        r = client.post(f"{task['url']}/cancel", headers=org.headers())
        assert r.status_code == 202 and r.json()["stopping"] == 1, r.text
        asked_s = time.monotonic() - t0
        got = wait_until(
            lambda: (v := client.get(task["url"], headers=org.headers()).json())["status"]
            != "running"
            and v,
            120,
            "the task to stop",
            step_s=0.05,
        )
        stopped_s = time.monotonic() - t0
    finally:
        w.stop()
    print(f"cancel route {asked_s:.2f} s, stopped after {stopped_s:.2f} s")
    assert got["status"] == "cancelled", got
    assert stopped_s < 3.0, (asked_s, stopped_s, w.log.read_text()[-3000:])
    db.rollback()
    assert db.scalar(text("SELECT count(*) FROM plans WHERE field_id = :f"), {"f": fid}) == 0
