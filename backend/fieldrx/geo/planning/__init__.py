"""Coverage planning in stages (docs/architecture.md "geo/planning/").

One module per stage, each usable on its own; :mod:`.planner` chains them:

* :mod:`.boundary` -- clean the field (repair, simplify traced noise), report changes;
* :mod:`.headland` -- headland rings around boundary and holes, the inner region;
* :mod:`.headings` -- candidate directions, swath-count bounds, objectives, the search;
* :mod:`.swaths` -- strips of the inner region and the swath of each strip piece;
* :mod:`.decomposition` -- boustrophedon blocks from the swaths' adjacency;
* :mod:`.order` -- block order (exact / greedy behind one interface), skip-row patterns;
* :mod:`.kinematics` and :mod:`.turns` -- the machine, drivable turns and transfers;
* :mod:`.metrics` -- coverage, overlap, route checks, turn warnings;
* :mod:`.frame` and :mod:`.model` -- the planning frame and the plan's data types
  (``StripGeometry`` is what the grid reads).

:mod:`fieldrx.geo.coverage` re-exports the public names. Nothing here imports the
database or the web.
"""
