"""Prescriptions in PostGIS: build (pure agronomy) -> versions + per-cell rates (COPY).

A prescription has immutable versions; version n's rates live in
``prescription_rates`` under that version's id, so an edit writes a whole new
rate set (n+1) and never touches n. The metering range the rates are checked
against is kept in ``prescriptions.params["meter"]`` so edits are checked the
same way: model outputs outside it are stored as computed and flagged, edits
outside it are refused (422 naming the limit and the speed).

One module per job: ``params`` (the request), ``plausibility``, ``classes`` (legend),
``meter``, ``samples`` (soil input), ``create`` (version 1), ``edits`` (later versions),
``versions`` (storing and reading versions back).
"""
