"""Job kinds: the registry of every kind and the sensor kinds' loops (seed 000 NDVI
topdressing, seed 002 depth-controlled seeding).

``registry``: the one list of kinds; each kind is a module of ``kinds/`` that registers
itself (name, settings and form, controllers, machine needs, entry points). ``settings``:
the checks every kind's settings share (the server's API and the agent run the same).
``sensors``: sensor line formats and the hold-then-stop guard. ``topdress`` / ``seeding``:
the loops the agent runs and the simulator drives. ``figures``: the per-speed-band tables
(the papers' Table 3) computed from records, the one definition used by the simulator,
the bench and the server's report.
"""
