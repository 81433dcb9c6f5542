"""Demo data: an organisation, an agronomist, a farm, a field near 32.13 N 112.32 E, a machine.

Idempotent: running it again changes nothing. The field is a 5 ha irregular
plot in Xiangyang (Hubei), the region of seed 001's trials.
"""

from __future__ import annotations

from dataclasses import dataclass

from geoalchemy2.shape import from_shape
from sqlalchemy import select
from sqlalchemy.orm import Session

from fieldrx.auth.service import add_membership, create_organisation, create_user
from fieldrx.db.models import Farm, Field, Machine, Organisation, User
from fieldrx.geo.validate import validate_boundary

DEMO_ORG = "Demo Farms Co."
DEMO_EMAIL = "agronomist@demo.fieldrx.org"
DEMO_PASSWORD = "fieldrx-demo"
DEMO_ADMIN_EMAIL = "admin@demo.fieldrx.org"
DEMO_VIEWER_EMAIL = "viewer@demo.fieldrx.org"

DEMO_FIELD = {
    "type": "Polygon",
    "coordinates": [
        [
            [112.3180, 32.1290],
            [112.3215, 32.1288],
            [112.3224, 32.1309],
            [112.3201, 32.1318],
            [112.3178, 32.1311],
            [112.3180, 32.1290],
        ]
    ],
}


DEMO_CALIBRATION = {
    "kind": "linear",
    "slope_g_min_per_rpm": 237.2,
    "intercept_g_min": -404.4,
    "min_rpm": 30.0,
    "max_rpm": 130.0,
}


@dataclass
class DemoInfo:
    organisation_id: int
    email: str
    password: str
    field_id: int
    machine_id: int


def seed_demo(session: Session) -> DemoInfo:
    org = session.scalar(select(Organisation).where(Organisation.name == DEMO_ORG))
    if org is None:
        org = create_organisation(session, DEMO_ORG)
        for email, role, name in (
            (DEMO_EMAIL, "agronomist", "Demo Agronomist"),
            (DEMO_ADMIN_EMAIL, "admin", "Demo Admin"),
            (DEMO_VIEWER_EMAIL, "viewer", "Demo Viewer"),
        ):
            user = session.scalar(select(User).where(User.email == email))
            if user is None:
                user = create_user(session, email, DEMO_PASSWORD, name)
            add_membership(session, user, org, role)
    farm = session.scalar(select(Farm).where(Farm.organisation_id == org.id))
    if farm is None:
        farm = Farm(organisation_id=org.id, name="Xiangyang Experimental Farm")
        session.add(farm)
        session.flush()
    field = session.scalar(select(Field).where(Field.organisation_id == org.id))
    if field is None:
        valid = validate_boundary(DEMO_FIELD)
        field = Field(
            organisation_id=org.id,
            farm_id=farm.id,
            name="North Rape Field",
            crop="winter oilseed rape",
            boundary=from_shape(valid.geometry, srid=4326),
            utm_epsg=valid.utm_epsg,
            area_m2=valid.area_m2,
        )
        session.add(field)
    machine = session.scalar(select(Machine).where(Machine.organisation_id == org.id))
    if machine is None:
        machine = Machine(
            organisation_id=org.id,
            name="Tractor 1 - disc spreader",
            implement_type="spreader",
            width_m=2.3,
            lag_s=1.52,
            # measured on this spreader: seed 001 eq. 1, q0 = 237.2 r - 404.4 g/min, 30..130 r/min
            calibration=DEMO_CALIBRATION,
            controller={"name": "ladrc", "params": {}, "period_s": 0.01},
            speed_min_m_s=3 / 3.6,
            speed_max_m_s=9 / 3.6,
        )
        session.add(machine)
    session.commit()
    return DemoInfo(org.id, DEMO_EMAIL, DEMO_PASSWORD, field.id, machine.id)
