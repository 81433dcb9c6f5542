"""ORM models: the whole FieldRx schema, one module per domain.

The schema itself changes only through Alembic revisions in ``migrations/``;
these classes describe it for queries. Geometries are stored in WGS84
(SRID 4326) with GiST indexes; metric work happens in the field's UTM zone,
whose EPSG code is stored beside the geometry.

This package is the models' public face: ``from fieldrx.db.models import X`` for every
model and constant, and importing it registers every table on ``Base.metadata`` (which
Alembic's environment reads).
"""

from fieldrx.db.models.accounts import ROLES, ApiToken, LoginFailure, Membership, Organisation, User
from fieldrx.db.models.base import Base
from fieldrx.db.models.farm import Farm, Field, Machine, Plan, PlanCell
from fieldrx.db.models.field_data import IMAGERY_KINDS, Imagery, SoilImport, SoilSample
from fieldrx.db.models.jobs import (
    JOB_STATES,
    CellRecordStream,
    Job,
    JobArchive,
    JobCellApplied,
    JobCellRecord,
    JobEvent,
)
from fieldrx.db.models.kinds import JOB_KINDS
from fieldrx.db.models.prescriptions import (
    Prescription,
    PrescriptionRate,
    PrescriptionVersion,
    Product,
)
from fieldrx.db.models.tasks import TASK_STATES, Task, TaskFile
from fieldrx.db.models.telemetry import (
    Alert,
    MachineStatus,
    Telemetry,
    TelemetryJobSpan,
    TelemetryStream,
)

__all__ = [
    "Base",
    "JOB_KINDS",
    "ROLES",
    "Organisation",
    "User",
    "Membership",
    "ApiToken",
    "LoginFailure",
    "Farm",
    "Field",
    "Machine",
    "Plan",
    "PlanCell",
    "SoilImport",
    "SoilSample",
    "IMAGERY_KINDS",
    "Imagery",
    "Prescription",
    "Product",
    "PrescriptionVersion",
    "PrescriptionRate",
    "JOB_STATES",
    "Job",
    "JobEvent",
    "JobCellApplied",
    "JobCellRecord",
    "CellRecordStream",
    "JobArchive",
    "Telemetry",
    "TelemetryStream",
    "TelemetryJobSpan",
    "MachineStatus",
    "Alert",
    "TASK_STATES",
    "Task",
    "TaskFile",
]
