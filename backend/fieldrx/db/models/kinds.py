"""The kinds of jobs and the check constraint that holds the ``jobs`` table to them: one
place, so that a change of the kinds touches one module and the database's check cannot
drift from the list the code reads. (Task kinds are a registry, ``tasks.kinds``, and
``tasks.kind`` a foreign key to the ``task_kinds`` rows written from it.)
"""

from __future__ import annotations

from sqlalchemy import CheckConstraint

JOB_KINDS = ("prescription_map", "ndvi_topdress", "seeding_depth")  # revision 0009


# a function, not a module constant: a constraint made when its table's class is built
# keeps its place among that table's constraints in the DDL
def job_kind_check() -> CheckConstraint:
    return CheckConstraint(f"kind IN {JOB_KINDS}", name="ck_job_kind")

