"""Sign-in, tokens, roles, organisation switching."""

from __future__ import annotations

import datetime as dt

from fieldrx.auth.security import token_digest
from fieldrx.db.models import ApiToken, User
from sqlalchemy import select


def test_login_and_me(client, org) -> None:
    r = client.post(
        "/api/v1/auth/login", json={"email": org.email("agronomist"), "password": org.password}
    )
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["token_type"] == "bearer"
    assert body["organisation"] == {"id": org.id, "name": org.name, "role": "agronomist"}
    me = client.get("/api/v1/auth/me", headers={"Authorization": f"Bearer {body['access_token']}"})
    assert me.status_code == 200
    assert me.json()["user"]["email"] == org.email("agronomist")


def test_login_wrong_password(client, org) -> None:
    r = client.post("/api/v1/auth/login", json={"email": org.email("admin"), "password": "nope"})
    assert r.status_code == 401
    assert "wrong e-mail or password" in r.json()["detail"]


def test_missing_and_bad_token(client) -> None:
    assert client.get("/api/v1/fields").status_code == 401
    r = client.get("/api/v1/fields", headers={"Authorization": "Bearer frx_u_nonsense"})
    assert r.status_code == 401
    assert "invalid" in r.json()["detail"]


def test_tokens_hashed_at_rest(db, org) -> None:
    rows = db.scalars(select(ApiToken).where(ApiToken.organisation_id == org.id)).all()
    assert rows
    stored = {r.token_hash for r in rows}
    for token in org.tokens.values():
        assert token not in stored
        assert token_digest(token) in stored


def test_password_hashed_with_argon2(db, org) -> None:
    user = db.get(User, org.user_ids["viewer"])
    assert user.password_hash.startswith("$argon2id$")
    assert org.password not in user.password_hash


def test_revoke_and_expiry(client, db, org) -> None:
    h = org.headers("admin")
    r = client.post(
        "/api/v1/auth/tokens", headers=h, json={"name": "farm software", "role": "viewer"}
    )
    assert r.status_code == 201, r.text
    new = r.json()
    th = {"Authorization": f"Bearer {new['token']}"}
    assert client.get("/api/v1/fields", headers=th).status_code == 200
    # a viewer token cannot write
    assert client.post("/api/v1/farms", headers=th, json={"name": "x"}).status_code == 403
    assert client.delete(f"/api/v1/auth/tokens/{new['id']}", headers=h).status_code == 204
    assert client.get("/api/v1/fields", headers=th).status_code == 401
    # expiry
    r = client.post("/api/v1/auth/tokens", headers=h, json={"name": "short", "role": "viewer"})
    row = db.get(ApiToken, r.json()["id"])
    row.expires_at = dt.datetime.now(dt.UTC) - dt.timedelta(seconds=1)
    db.commit()
    assert (
        client.get(
            "/api/v1/fields", headers={"Authorization": f"Bearer {r.json()['token']}"}
        ).status_code
        == 401
    )


def test_cannot_create_token_above_own_role(client, org) -> None:
    r = client.post(
        "/api/v1/auth/tokens",
        headers=org.headers("agronomist"),
        json={"name": "x", "role": "admin"},
    )
    assert r.status_code == 403


def test_logout_revokes(client, org) -> None:
    r = client.post(
        "/api/v1/auth/login", json={"email": org.email("viewer"), "password": org.password}
    )
    h = {"Authorization": f"Bearer {r.json()['access_token']}"}
    assert client.post("/api/v1/auth/logout", headers=h).status_code == 204
    assert client.get("/api/v1/auth/me", headers=h).status_code == 401


def test_organisation_switch(client, db, make_org) -> None:
    from fieldrx.auth.service import add_membership
    from fieldrx.db.models import Organisation

    a, b = make_org(), make_org()
    user = db.get(User, a.user_ids["agronomist"])
    add_membership(db, user, db.get(Organisation, b.id), "viewer")
    db.commit()
    r = client.post(
        "/api/v1/auth/login", json={"email": a.email("agronomist"), "password": a.password}
    )
    assert [o["id"] for o in r.json()["organisations"]] == [a.id, b.id]
    h = {"Authorization": f"Bearer {r.json()['access_token']}"}
    s = client.post("/api/v1/auth/switch", headers=h, json={"organisation_id": b.id})
    assert s.status_code == 200
    assert s.json()["organisation"] == {"id": b.id, "name": b.name, "role": "viewer"}
    other = make_org()
    assert (
        client.post(
            "/api/v1/auth/switch", headers=h, json={"organisation_id": other.id}
        ).status_code
        == 404
    )
