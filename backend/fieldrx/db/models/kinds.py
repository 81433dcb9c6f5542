"""The kinds of jobs and of background tasks, and the check constraints that hold the
``jobs`` and ``tasks`` tables to them: one place, so that a change of the kinds touches
one module and the database's checks cannot drift from the lists the code reads.
"""

from __future__ import annotations

from sqlalchemy import CheckConstraint

JOB_KINDS = ("prescription_map", "ndvi_topdress", "seeding_depth")  # revision 0009
TASK_KINDS = ("plan", "prescription", "imagery", "plan_batch")  # revision 0012


# functions, not module constants: a constraint made when its table's class is built
# keeps its place among that table's constraints in the DDL
def job_kind_check() -> CheckConstraint:
    return CheckConstraint(f"kind IN {JOB_KINDS}", name="ck_job_kind")


def task_kind_check() -> CheckConstraint:
    return CheckConstraint(
        "kind IN ('plan', 'prescription', 'imagery', 'plan_batch', 'export', 'report')",
        name="ck_tasks_kind",
    )
