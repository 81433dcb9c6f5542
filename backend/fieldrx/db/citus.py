"""Past one node: which tables Citus distributes, the rules it enforces, and the switch.

The machine-keyed tables are distributed by machine and co-located (same shard count,
same column), so one ingest batch, one report or one track is a single-shard transaction;
a few small tables every request reads are reference tables (copied to every node); the
rest (fields, plans, prescriptions, imagery, tasks, ...) stays on the coordinator
(docs/scale.md section 2).

``problems`` reads a database's catalog and lists everything Citus would refuse for that
layout (each rule was met on a real Citus 13 cluster); it needs no Citus, so the test suite
checks the schema on plain PostgreSQL. ``upsert_problems`` does the same for SQL text:
Citus refuses a function that is not IMMUTABLE in an upsert's ``DO UPDATE SET``.
``distribute`` is ``fieldrx distribute``: on the coordinator, after ``fieldrx migrate``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

import psycopg

REFERENCE = ("organisations", "users", "memberships", "api_tokens", "task_kinds")
ANCHOR = ("machines", "id")  # the co-location group's first table and its column
COLOCATED = (
    "telemetry",
    "telemetry_streams",
    "telemetry_job_spans",
    "machine_status",
    "alerts",
    "jobs",
    "job_events",
    "job_cells_applied",
    "job_cell_records",
    "cell_record_streams",
)
DISTRIBUTED: dict[str, str] = {ANCHOR[0]: ANCHOR[1], **{t: "machine_id" for t in COLOCATED}}

# every foreign key and unique key of the public schema's tables (partitions inherit theirs)
_CONSTRAINTS = """
SELECT c.conname, c.contype, r.relname, f.relname,
       ARRAY(SELECT a.attname FROM unnest(c.conkey) WITH ORDINALITY k(n, i)
             JOIN pg_attribute a ON a.attrelid = c.conrelid AND a.attnum = k.n ORDER BY k.i),
       ARRAY(SELECT a.attname FROM unnest(c.confkey) WITH ORDINALITY k(n, i)
             JOIN pg_attribute a ON a.attrelid = c.confrelid AND a.attnum = k.n ORDER BY k.i),
       c.confupdtype, c.confdeltype, pg_get_constraintdef(c.oid)
FROM pg_constraint c
JOIN pg_class r ON r.oid = c.conrelid
JOIN pg_namespace n ON n.oid = r.relnamespace
LEFT JOIN pg_class f ON f.oid = c.confrelid
WHERE n.nspname = 'public' AND c.contype IN ('f', 'p', 'u', 'x') AND NOT r.relispartition
  AND c.conparentid = 0
ORDER BY r.relname, c.conname
"""

# unique indexes that are not a constraint's
_UNIQUE_INDEXES = """
SELECT i.relname, r.relname,
       ARRAY(SELECT a.attname FROM unnest(x.indkey) k(n)
             JOIN pg_attribute a ON a.attrelid = x.indrelid AND a.attnum = k.n)
FROM pg_index x
JOIN pg_class i ON i.oid = x.indexrelid
JOIN pg_class r ON r.oid = x.indrelid
JOIN pg_namespace n ON n.oid = r.relnamespace
WHERE n.nspname = 'public' AND x.indisunique AND NOT r.relispartition
  AND NOT EXISTS (SELECT 1 FROM pg_constraint c WHERE c.conindid = x.indexrelid)
"""


@dataclass(frozen=True)
class Constraint:
    name: str
    kind: str  # p, u, x, f
    table: str
    target: str | None
    columns: tuple[str, ...]
    target_columns: tuple[str, ...]
    on_update: str  # pg_constraint.confupdtype: a = NO ACTION, r = RESTRICT, c = CASCADE ...
    on_delete: str
    definition: str


def constraints(conn: psycopg.Connection[Any]) -> list[Constraint]:
    rows = conn.execute(_CONSTRAINTS).fetchall()
    return [
        Constraint(r[0], r[1], r[2], r[3], tuple(r[4]), tuple(r[5] or ()), r[6], r[7], r[8])
        for r in rows
    ]


def _key_problem(c: Constraint) -> str | None:
    col = DISTRIBUTED.get(c.table)
    if col is None or c.kind == "f" or col in c.columns:
        return None
    return f"{c.table}: key {c.name} {c.columns} lacks the distribution column {col}"


def _same_place(c: Constraint) -> bool:
    """Whether the foreign key pairs the distribution columns of both tables."""
    src, dst = DISTRIBUTED[c.table], DISTRIBUTED[c.target or ""]
    return any(a == src and b == dst for a, b in zip(c.columns, c.target_columns, strict=True))


def _fkey_problem(c: Constraint) -> str | None:
    if c.kind != "f" or c.target is None:
        return None
    src_dist, dst_dist = c.table in DISTRIBUTED, c.target in DISTRIBUTED
    where = f"{c.table}: foreign key {c.name} -> {c.target}"
    if c.on_update not in ("a", "r") and (src_dist or dst_dist or c.table in REFERENCE):
        return f"{where} has an ON UPDATE action (Citus allows none)"
    if dst_dist and not src_dist:
        kind = "reference" if c.table in REFERENCE else "coordinator"
        return f"{where}: a {kind} table cannot reference a distributed table"
    if src_dist and dst_dist and not _same_place(c):
        return f"{where} does not pair the distribution columns"
    if src_dist and not dst_dist and c.target not in REFERENCE:
        return f"{where}: a distributed table can reference only co-located or reference tables"
    if c.table in REFERENCE and c.target not in REFERENCE:
        return f"{where}: a reference table can reference only reference tables"
    return None


def problems(conn: psycopg.Connection[Any]) -> list[str]:
    """What Citus would refuse, for the layout above, in this database's schema."""
    found: list[str] = []
    tables = {
        r[0] for r in conn.execute("SELECT tablename FROM pg_tables WHERE schemaname = 'public'")
    }
    found += [f"{t}: table missing" for t in (*REFERENCE, *DISTRIBUTED) if t not in tables]
    for c in constraints(conn):
        found += [p for p in (_key_problem(c), _fkey_problem(c)) if p]
    for index, table, cols in conn.execute(_UNIQUE_INDEXES).fetchall():
        col = DISTRIBUTED.get(table)
        if col is not None and col not in cols:
            found.append(f"{table}: unique index {index} {tuple(cols)} lacks {col}")
    return found


# -- SQL text: upserts -------------------------------------------------------------------

_CALL = re.compile(r"\b([a-z_][a-z0-9_]*)\s*\(", re.IGNORECASE)
_NOT_FUNCTIONS = {
    "coalesce", "greatest", "least", "nullif", "exists", "in", "any", "all", "array", "row",
    "values", "case", "cast", "and", "or", "not", "when", "then", "else", "set", "where",
}  # fmt: skip


def do_update_clauses(sql: str) -> list[str]:
    """The ``DO UPDATE SET ...`` clauses of ``sql``: each up to its statement's end, its
    RETURNING, or the parenthesis that closes the CTE it is in."""
    out = []
    for m in re.finditer(r"\bDO\s+UPDATE\b", sql, re.IGNORECASE):
        depth, i = 0, m.end()
        while i < len(sql):
            ch = sql[i]
            if ch == "(":
                depth += 1
            elif ch == ")":
                depth -= 1
                if depth < 0:
                    break
            elif ch == ";" or (depth == 0 and sql[i : i + 9].upper() == "RETURNING"):
                break
            i += 1
        out.append(sql[m.end() : i])
    return out


def upsert_problems(conn: psycopg.Connection[Any], sql: str) -> list[str]:
    """Functions in ``sql``'s upsert ``DO UPDATE`` clauses that are not IMMUTABLE (Citus:
    "functions used in the DO UPDATE SET clause of INSERTs on distributed tables must be
    marked IMMUTABLE"): ``now()`` there must become the inserted row's value (EXCLUDED)."""
    found = []
    for clause in do_update_clauses(sql):
        for name in {m.group(1).lower() for m in _CALL.finditer(clause)} - _NOT_FUNCTIONS:
            row = conn.execute(
                "SELECT bool_and(provolatile = 'i') FROM pg_proc WHERE proname = %s", (name,)
            ).fetchone()
            if row is not None and row[0] is False:
                found.append(f"{name}() is not IMMUTABLE in: DO UPDATE{' '.join(clause.split())}")
    return found


# -- fieldrx distribute ------------------------------------------------------------------


class NotReady(Exception):
    """The database cannot be distributed (no citus extension, or the schema breaks a rule)."""


@dataclass
class Report:
    reference: list[str] = field(default_factory=list)
    distributed: list[str] = field(default_factory=list)
    already: list[str] = field(default_factory=list)
    foreign_keys: list[str] = field(default_factory=list)
    workers: int = 0


def _citus_kinds(conn: psycopg.Connection[Any]) -> dict[str, str]:
    rows = conn.execute(
        "SELECT logicalrelid::regclass::text, partmethod FROM pg_dist_partition"
    ).fetchall()
    return {r[0]: r[1] for r in rows}  # h: hash-distributed, n: reference or local


def _is_reference(conn: psycopg.Connection[Any], table: str) -> bool:
    row = conn.execute(
        "SELECT citus_table_type FROM citus_tables WHERE table_name = %s::regclass", (table,)
    ).fetchone()
    return row is not None and row[0] == "reference"


def check_ready(conn: psycopg.Connection[Any]) -> None:
    has = conn.execute("SELECT 1 FROM pg_extension WHERE extname = 'citus'").fetchone()
    if not has:
        db = conn.info.dbname
        raise NotReady(
            f"database {db!r} has no citus extension: install Citus on the coordinator and"
            " every worker, load it (shared_preload_libraries = 'citus'), then as superuser"
            f" CREATE EXTENSION citus in {db!r} and add the workers"
            " (SELECT citus_add_node(host, port)); nothing was changed"
        )
    found = problems(conn)
    if found:
        raise NotReady(
            "the schema breaks Citus's rules (run `fieldrx migrate` first?); nothing was"
            " changed:\n  " + "\n  ".join(found)
        )


def distribute(conn: psycopg.Connection[Any]) -> Report:
    """Make the reference tables, then distribute the machine-keyed ones co-located with
    ``machines``; a second run finds everything done and changes nothing.

    Citus distributes a table only while no local table references it and it references
    no local table; so the foreign keys among the machine-keyed tables are dropped, the
    tables distributed, and the same keys re-added (now between co-located tables), all in
    one transaction: on any error nothing has changed."""
    check_ready(conn)
    rep = Report()
    rep.workers = int(
        conn.execute(
            "SELECT count(*) FROM pg_dist_node WHERE groupid <> 0 AND noderole = 'primary'"
        ).fetchone()[0]  # type: ignore[index]
    )
    with conn.transaction():
        # DDL and distribution in one transaction: Citus must use one connection per node
        conn.execute("SET LOCAL citus.multi_shard_modify_mode TO 'sequential'")
        kinds = _citus_kinds(conn)
        todo = [t for t in DISTRIBUTED if kinds.get(t) != "h"]
        rep.already += [t for t in DISTRIBUTED if t not in todo]
        between = [
            c
            for c in constraints(conn)
            if c.kind == "f" and c.table in DISTRIBUTED and c.target in DISTRIBUTED
            and (c.table in todo or c.target in todo)
        ]  # fmt: skip
        for c in between:
            conn.execute(f'ALTER TABLE "{c.table}" DROP CONSTRAINT "{c.name}"')
        for t in REFERENCE:
            if _is_reference(conn, t):
                rep.already.append(t)
            else:
                conn.execute("SELECT create_reference_table(%s)", (t,))
                rep.reference.append(t)
        for t in todo:
            if t == ANCHOR[0]:
                conn.execute("SELECT create_distributed_table(%s, %s)", ANCHOR)
            else:
                conn.execute(
                    "SELECT create_distributed_table(%s, %s, colocate_with => %s)",
                    (t, DISTRIBUTED[t], ANCHOR[0]),
                )
            rep.distributed.append(t)
        for c in between:
            conn.execute(f'ALTER TABLE "{c.table}" ADD CONSTRAINT "{c.name}" {c.definition}')
            rep.foreign_keys.append(f"{c.table}.{c.name}")
    return rep
