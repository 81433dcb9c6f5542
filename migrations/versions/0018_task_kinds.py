"""Task kinds in a table of their own, filled from the code's task-kind registry.

Why: the kinds of background task were listed four times and disagreed (the queues, the
worker's dispatch, the result links, the models' stale list) besides this check, which
every new kind had to widen with a migration (0015, 0017_i32b). ``tasks.kind`` now
refers to ``task_kinds(name)``; ``fieldrx migrate`` inserts the kinds the code registers
(``fieldrx.tasks.kinds.sync_task_kinds``) after the migrations, so a new kind needs none.
The rows below are the kinds known at this revision (the check's list), so tasks already
stored keep a row. Past one node ``task_kinds`` is a reference table (``db.citus``).

Revision ID: 0018_task_kinds
Revises: 0017_i32b_import_tasks
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0018_task_kinds"
down_revision: str | Sequence[str] | None = "0017_i32b_import_tasks"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

KINDS = ("plan", "prescription", "imagery", "plan_batch", "export", "report", "import")
OLD_CHECK = f"kind IN {KINDS}"


def upgrade() -> None:
    table = op.create_table(
        "task_kinds",
        sa.Column("name", sa.String(32), nullable=False),
        sa.PrimaryKeyConstraint("name", name="task_kinds_pkey"),
    )
    op.bulk_insert(table, [{"name": k} for k in KINDS])
    op.drop_constraint("ck_tasks_kind", "tasks", type_="check")
    op.create_foreign_key("tasks_kind_fkey", "tasks", "task_kinds", ["kind"], ["name"])


def downgrade() -> None:
    op.execute(f"DELETE FROM tasks WHERE NOT ({OLD_CHECK})")
    op.drop_constraint("tasks_kind_fkey", "tasks", type_="foreignkey")
    op.create_check_constraint("ck_tasks_kind", "tasks", OLD_CHECK)
    op.drop_table("task_kinds")
