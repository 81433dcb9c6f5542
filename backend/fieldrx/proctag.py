"""A tag naming the process that writes a file, so what a crash left can be told apart
from what a live process is still writing.

Files a request or task writes before it records them (spooled uploads, received
imagery, COGs being converted) carry ``<pid>x<start>`` in their names: the process id
and its start time in clock ticks since boot (``/proc/<pid>/stat`` field 22). A tag is
alive while a process with that id and that start time exists, so a reused process id
(a restarted container's API is often pid 1 again) does not keep a dead writer's files.
"""

from __future__ import annotations

import os


def _start_ticks(pid: int) -> str | None:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            stat = fh.read()
    except OSError:
        return None
    # the command name (field 2) may hold spaces and parentheses: split after its ")"
    fields = stat[stat.rindex(")") + 2 :].split()
    if fields[0] == "Z":  # a zombie has finished
        return None
    return fields[19]  # field 22 of the whole line: starttime


def process_tag(pid: int | None = None) -> str:
    """This process's tag (see module docstring)."""
    p = os.getpid() if pid is None else pid
    return f"{p}x{_start_ticks(p) or 0}"


def tag_alive(tag: str) -> bool:
    """Whether the process that made ``tag`` is still running (unknown forms: True)."""
    pid, _, start = tag.partition("x")
    if not pid.isdigit() or not start.isdigit():
        return True
    return _start_ticks(int(pid)) == start


def tag_of(name: str) -> str | None:
    """The tag a file name starts with (``<tag>-...``), or None."""
    head, sep, _ = name.partition("-")
    return head if sep and "x" in head else None
