"""`fieldrx-edge simulate JOB_ID --state-dir D` finds a job cached by `pull`.

Before the fix, ``simulate`` looked only for a file or a ``demo:`` spec and answered
"no such file or cached job id" for a job that ``run`` found in the same state dir.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from fieldrx_edge import cli
from fieldrx_edge.jobs import JobStore
from fieldrx_edge.sim.fields import RectField, rect_job


def test_simulate_runs_a_cached_job(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    job = rect_job(RectField(length_m=35.0, width_m=23.0))
    JobStore(tmp_path).save_package(job.to_json())
    rc = cli.main(["simulate", str(job.job_id), "--state-dir", str(tmp_path), "--json"])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    assert out["field"] == "sim 35 m x 23 m" and out["cells"] == 70


def test_simulate_unknown_cached_id_names_the_state_dir(tmp_path: Path) -> None:
    with pytest.raises(SystemExit, match="999"):
        cli.main(["simulate", "999", "--state-dir", str(tmp_path), "--json"])
