"""Interchange: imports, reference lines, external as-applied; reserved revision.

Revision ID: 0009_interchange
Revises: 0008_mqtt_credentials
"""

from __future__ import annotations

from collections.abc import Sequence

revision: str = "0009_interchange"
down_revision: str | Sequence[str] | None = "0008_mqtt_credentials"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    pass


def downgrade() -> None:
    pass
