"""A cursor that records statements and answers from a script: the database stages'
decisions (which statements, with which parameters) tested without a database."""

from __future__ import annotations

from typing import Any


class ScriptedCursor:
    """``execute`` records (sql, params); ``fetchone`` / ``fetchall`` pop ``answers`` in
    order (each answer is what that fetch returns)."""

    def __init__(self, *answers: Any) -> None:
        self.answers = list(answers)
        self.executed: list[tuple[str, Any]] = []

    def execute(self, sql: str, params: Any = None) -> None:
        self.executed.append((sql, params))

    def fetchone(self) -> Any:
        return self.answers.pop(0)

    def fetchall(self) -> Any:
        return self.answers.pop(0)
