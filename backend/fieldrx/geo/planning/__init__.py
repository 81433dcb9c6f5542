"""Coverage planning in stages (issue 16, DESIGN.md "geo/planning/").

One module per stage, each usable on its own:

* :mod:`.boundary` -- clean the field (repair, simplify traced noise), report changes;
* :mod:`.kinematics` -- the machine: turning radius, reverse, turn speed;
* :mod:`.turns` -- drivable turns between swaths (Dubins U / bulb, fishtail) and
  drivable transfers along router paths;
* the swath layout, decomposition, heading objectives, block order and metrics still
  live in :mod:`fieldrx.geo.coverage` (see the report of issue 16 for what is split).

Nothing here imports the database or the web.
"""
