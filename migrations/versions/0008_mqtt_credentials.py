"""MQTT credentials bound to device tokens: no schema change.

Reserved while the work was planned in parallel; the broker's dynamic-security
plugin holds the machine users (a salted hash of the device token), so the
database needed nothing. Kept (empty) because databases already stamped with
this revision must keep upgrading.

Revision ID: 0008_mqtt_credentials
Revises: 0007_hardening
"""

from __future__ import annotations

from collections.abc import Sequence

revision: str = "0008_mqtt_credentials"
down_revision: str | Sequence[str] | None = "0007_hardening"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    pass


def downgrade() -> None:
    pass
