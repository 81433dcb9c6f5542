"""Background work on a PostgreSQL-backed queue, with progress.

Planning, prescriptions and imagery ingest can run outside the HTTP request as *tasks*,
executed by ``fieldrx worker`` processes (any number, on any host that reaches the
database). The queue is procrastinate's (its tables come from revision 0012): it hands
each job to exactly one worker, and a job whose worker stops sending heartbeats is handed
to another (``tasks.worker``: stalled-job recovery). FieldRx's ``tasks`` table
(``db.models.Task``) is what users see: organisation scoping, progress 0..1 with a
message, the result, an error they can act on, cancellation.

Modules:

- ``store``: task rows (create with the queue job in one transaction, read, cancel, the
  state changes a worker makes) and their API view;
- ``queue``: the procrastinate app and how jobs of the one queue task,
  ``fieldrx.run_task``, are made (deferred by name from the API);
- ``kinds``: the task-kind registry (``TASK_KINDS``: each kind's name, queue, result
  route and run), which the ``task_kinds`` table is filled from;
- ``work``: what the plan, prescription and imagery kinds do, run in a child process
  with a time limit (``services.bounded``) and finished under the task's guard (below),
  and the dispatch by kind through the registry (importing it registers every kind);
- ``context``: what the kinds' work runs with (progress, input errors, the one
  transaction that stores a result and completes its task);
- ``exports``: the export and job-report kinds; ``files``: the files they produce
  (stored with the task's success, downloaded in slices, purged after a retention);
- ``imports``: the confirmed ISOXML import kind;
- ``worker``: the queue task's code, the worker loop, stalled-job recovery and the purge
  of old files.

Exactly once: a killed worker's job runs again on another worker, and the killed
worker's child may even still be finishing. Every kind therefore writes its result and
marks its task ``succeeded`` in ONE transaction, taken under a per-task advisory lock and
only if the task is not already ``succeeded``; a second run finds the result and stores
nothing. So a plan is stored once however often its job runs.
"""

from __future__ import annotations

TASK_LOCK_NS = 7003  # advisory lock namespace (fleet.ingest 7001, fleet.alerts 7002, plans 7004)
QUOTA_LOCK_NS = 7005  # an organisation's task quota is counted under this lock (store)
