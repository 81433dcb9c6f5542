"""ISOXML imports as background tasks (kind ``import``).

Why: a confirmed TASKDATA import plans and stores every field and prescription of the
set, which for a large grid took tens of seconds inside the HTTP request with no
progress. A large confirm (or any, asked with ``background=true``) now runs as a task of
kind ``import``; the tasks table's kind check has to admit it.

Revision ID: 0017_i32b_import_tasks
Revises: 0017_i35_field_area_utm
"""

from __future__ import annotations

from collections.abc import Sequence

from alembic import op

revision: str = "0017_i32b_import_tasks"
down_revision: str | Sequence[str] | None = "0017_i35_field_area_utm"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

OLD_KINDS = "kind IN ('plan', 'prescription', 'imagery', 'plan_batch', 'export', 'report')"
NEW_KINDS = (
    "kind IN ('plan', 'prescription', 'imagery', 'plan_batch', 'export', 'report', 'import')"
)


def upgrade() -> None:
    op.drop_constraint("ck_tasks_kind", "tasks", type_="check")
    op.create_check_constraint("ck_tasks_kind", "tasks", NEW_KINDS)


def downgrade() -> None:
    op.execute("DELETE FROM tasks WHERE kind = 'import'")
    op.drop_constraint("ck_tasks_kind", "tasks", type_="check")
    op.create_check_constraint("ck_tasks_kind", "tasks", OLD_KINDS)
