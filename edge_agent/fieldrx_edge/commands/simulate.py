"""``simulate``: drive a job in simulation, through the same ``JobSession`` as ``run``."""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
from typing import Any

from fieldrx_edge.commands.run import motor_job
from fieldrx_edge.commands.sessions import finished_early, session_report, sim_session
from fieldrx_edge.jobkinds.registry import kind_of
from fieldrx_edge.jobs import JobStore
from fieldrx_edge.session import JobFinished, load_job


def cmd_simulate(a: argparse.Namespace) -> int:
    from fieldrx_edge.sim.simulator import SimConfig, simulate, summary

    # a cached job id works as with `run` (pulled into --state-dir or the default one)
    job = load_job(a.job, JobStore(a.state_dir) if a.job.isdigit() else None)
    own = kind_of(job.kind).simulate(a, job)  # a kind with its own simulator (sensor kinds)
    if own is not None:
        return own
    lo, hi = a.speed
    cfg = SimConfig(
        speed_min_kmh=lo,
        speed_max_kmh=hi,
        gnss_noise_m=a.gnss_noise,
        speed_noise_m_s=a.speed_noise,
        controller=a.controller,
        lag_compensation=a.lag_compensation,
        seed=a.seed,
        gnss_hz=a.gnss_hz,
        realtime=a.realtime,
    )
    pair = None
    if a.implement != "isobus":
        job = motor_job(job)
    if a.implement == "isobus":
        from fieldrx_edge.isobus.pair import IsobusPair

        pair = IsobusPair(job, sections=a.sections)
        pair.connect()
        cfg = dataclasses.replace(cfg, implement=pair)
    session = sim_session(a, job, a.uplink if a.server else "full")
    operator = session.operator
    if operator is not None:  # the cab's buttons act where the implement stands
        operator.inner = cfg.implement
        cfg = dataclasses.replace(cfg, implement=operator)
    session.start(report=True)
    sink = session.put_many if (a.server or operator is not None) else None
    try:
        res = simulate(job, cfg, sink=sink)
    except JobFinished:
        return finished_early(a, session, pair)
    if session.thin is not None:
        session.thin.flush()
    res_u = None
    if a.lag_compensation:
        res_u = simulate(
            job,
            dataclasses.replace(cfg, lag_compensation=False, implement=None),
            max_runs=a.compare_runs,
        )
    out = summary(res, res_u if res_u is not None else res, cfg, job)
    out["uncompensated_runs"] = a.compare_runs if res_u is not None else "all"
    out["implement"] = a.implement
    if pair is not None:
        from fieldrx_edge.commands.run import isobus_stats

        out["isobus"] = isobus_stats(pair.tc)
        pair.close()
    if res_u is None:
        out["uncompensated_borders"] = out["lag_borders"]
    # the simulated tractor drove the whole path: the job is done
    session_report(session, out)
    if a.cells_out:
        write_cells(a.cells_out, res)
    if not a.json or a.verbose:
        print_cells(res, out, a.verbose)
    if a.json:
        print(json.dumps(out), flush=True)
    if session.cab is not None:
        session.cab.finish()  # the summary on the screen, after the figures are out
    return 0


def write_cells(path: str, res: Any) -> None:
    # m2/accuracy: what physically landed (the simulated truth); logged_*: the
    # as-applied kernel over the records the agent sent (the server's report)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(
            ["seq", "rate_kg_ha", "m1_g", "m2_g", "accuracy_pct", "logged_m2_g",
             "logged_accuracy_pct"]
        )  # fmt: skip
        for s, r, m1, m2, acc, lm2, lacc in zip(
            res.extra["seq"],
            res.extra["rate"],
            res.cell_m1_g,
            res.cell_m2_g,
            res.cell_accuracy_pct,
            res.extra["logged_m2_g"],
            res.extra["logged_accuracy_pct"],
            strict=True,
        ):
            w.writerow(
                [
                    int(s),
                    float(r),
                    round(float(m1), 4),
                    round(float(m2), 4),
                    round(float(acc), 4),
                    round(float(lm2), 4),
                    round(float(lacc), 4),
                ]
            )


def print_cells(res: Any, out: dict[str, Any], verbose: bool) -> None:
    import numpy as np

    seqs = res.extra["seq"]
    acc = res.cell_accuracy_pct
    limit = len(acc) if verbose else min(len(acc), 100)
    print("cell  rate_kg_ha  M1_g     M2_g     accuracy_%")
    for i in range(limit):
        print(
            f"{int(seqs[i]):5d} {res.extra['rate'][i]:8.1f} {res.cell_m1_g[i]:9.1f}"
            f" {res.cell_m2_g[i]:9.1f}   {acc[i]:6.2f}"
        )
    if limit < len(acc):
        print(f"... {len(acc) - limit} more cells (--cells-out FILE for all)")
    print(
        f"mean accuracy {out['mean_accuracy_pct']} %, min {out['min_accuracy_pct']} %;"
        f" mean lag at borders {out['mean_lag_m']} m (uncompensated"
        f" {out.get('mean_lag_uncompensated_m')} m); outside the field"
        f" {out['applied_outside_kg']} kg; {np.round(res.wall_s, 1)} s"
    )
