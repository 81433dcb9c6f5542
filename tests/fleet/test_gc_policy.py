"""The ingest processes' cyclic GC settings (fleet.gc_policy).

Run in a fresh interpreter: the settings are process-wide and ``gc.freeze`` is once per
process, so the test process's own state would say nothing."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from tests.support import scaled

ROOT = Path(__file__).resolve().parents[2]

PROBE = """
import gc
from fieldrx.fleet.gc_policy import GEN0_THRESHOLD, tune_for_ingest
assert gc.get_threshold()[0] < GEN0_THRESHOLD, gc.get_threshold()
assert gc.get_freeze_count() == 0
{setup}
assert gc.get_threshold()[0] == GEN0_THRESHOLD, gc.get_threshold()
frozen = gc.get_freeze_count()
assert frozen > 1000, frozen  # the start-up heap: modules, classes
junk = [[i] for i in range(5000)]
tune_for_ingest()  # again: the threshold stays, nothing more is frozen
assert gc.get_threshold()[0] == GEN0_THRESHOLD
assert gc.get_freeze_count() == frozen, (gc.get_freeze_count(), frozen)
print("ok")
"""


def _probe(setup: str) -> None:
    env = {**os.environ, "PYTHONPATH": f"{ROOT / 'backend'}{os.pathsep}{ROOT / 'edge_agent'}"}
    out = subprocess.run(
        [sys.executable, "-c", PROBE.format(setup=setup)],
        capture_output=True, text=True, env=env, timeout=scaled(120),
    )  # fmt: skip
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]


def test_tune_for_ingest_raises_gen0_and_freezes_once() -> None:
    _probe("tune_for_ingest()")


def test_the_api_process_is_tuned() -> None:
    """uvicorn builds the app with ``create_app`` in each worker process: the HTTP ingest
    path parses its bodies under the same settings as the MQTT worker."""
    _probe("from fieldrx.app import create_app\ncreate_app()")
