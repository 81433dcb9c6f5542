"""Soil imports (list / delete / duplicate check) and the job's flagged-cell confirmation.

Why: samples from another field were stored and interpolated without a word, the
same file uploaded twice doubled the samples, and the UI could not delete them;
``soil_imports`` records each upload (sha256 of its bytes, unique per field) and
its samples are deleted with it. A job whose prescription has cells with no data
or outside the machine's meter range is sent only on explicit confirmation:
``jobs.flagged_cells`` / ``jobs.flagged_confirmed`` record what was confirmed.
Machine calibrations stay in ``machines.calibration`` (required by the API now).

Revision ID: 0005_calibration_flags
Revises: 0004_telemetry_streams
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0005_calibration_flags"
down_revision: str | Sequence[str] | None = "0004_telemetry_streams"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "soil_imports",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("organisation_id", sa.Integer(), nullable=False),
        sa.Column("field_id", sa.Integer(), nullable=False),
        sa.Column("filename", sa.String(length=255), nullable=False),
        sa.Column("sha256", sa.String(length=71), nullable=False),
        sa.Column("batch", sa.String(length=64), nullable=False),
        sa.Column("n_samples", sa.Integer(), nullable=False),
        sa.Column("n_outside", sa.Integer(), nullable=False),
        sa.Column("outside_stored", sa.Boolean(), nullable=False),
        sa.Column("created_by", sa.Integer(), nullable=True),
        sa.Column(
            "created_at",
            sa.DateTime(timezone=True),
            server_default=sa.text("now()"),
            nullable=False,
        ),
        sa.ForeignKeyConstraint(["created_by"], ["users.id"], ondelete="SET NULL"),
        sa.ForeignKeyConstraint(["field_id"], ["fields.id"], ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["organisation_id"], ["organisations.id"], ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("id"),
        sa.UniqueConstraint("field_id", "sha256", name="uq_soil_imports_field_sha256"),
    )
    op.create_index("ix_soil_imports_field_id", "soil_imports", ["field_id"])
    op.create_index("ix_soil_imports_organisation_id", "soil_imports", ["organisation_id"])
    op.add_column("soil_samples", sa.Column("import_id", sa.Integer(), nullable=True))
    op.create_foreign_key(
        "soil_samples_import_id_fkey",
        "soil_samples",
        "soil_imports",
        ["import_id"],
        ["id"],
        ondelete="CASCADE",
    )
    op.create_index("ix_soil_samples_import_id", "soil_samples", ["import_id"])
    # Samples imported before this revision: one import per (field, batch), so they can
    # be listed and deleted like new ones (their file is unknown: "legacy:" digest).
    op.execute(
        "INSERT INTO soil_imports (organisation_id, field_id, filename, sha256, batch, "
        "n_samples, n_outside, outside_stored, created_at) "
        "SELECT organisation_id, field_id, '', 'legacy:' || md5(field_id || ':' || import_batch),"
        " import_batch, count(*), 0, false, min(created_at) FROM soil_samples "
        "GROUP BY organisation_id, field_id, import_batch"
    )
    op.execute(
        "UPDATE soil_samples s SET import_id = i.id FROM soil_imports i "
        "WHERE i.field_id = s.field_id AND i.batch = s.import_batch"
    )
    op.add_column(
        "jobs", sa.Column("flagged_cells", sa.Integer(), server_default="0", nullable=False)
    )
    op.add_column(
        "jobs",
        sa.Column("flagged_confirmed", sa.Boolean(), server_default="false", nullable=False),
    )


def downgrade() -> None:
    op.drop_column("jobs", "flagged_confirmed")
    op.drop_column("jobs", "flagged_cells")
    op.drop_index("ix_soil_samples_import_id", table_name="soil_samples")
    op.drop_constraint("soil_samples_import_id_fkey", "soil_samples", type_="foreignkey")
    op.drop_column("soil_samples", "import_id")
    op.drop_index("ix_soil_imports_organisation_id", table_name="soil_imports")
    op.drop_index("ix_soil_imports_field_id", table_name="soil_imports")
    op.drop_table("soil_imports")
