"""Sensor job kinds: seed 000 NDVI topdressing and seed 002 depth-controlled seeding.

``settings``: each kind's settings with units and the paper's defaults, validated (shared by
the server's API and the agent). ``sensors``: sensor line formats and the hold-then-stop
guard. ``topdress`` / ``seeding``: the loops the agent runs and the simulator drives.
``figures``: the per-speed-band tables (the papers' Table 3) computed from records, the
one definition used by the simulator, the bench and the server's report.
"""
