"""Telemetry ingest in stages (docs/architecture.md "fleet/ingest/").

One module per stage, each usable on its own; :mod:`.pipeline` chains them for one
telemetry batch (``pipeline.ingest``, ``pipeline.TrackWork``):

* :mod:`.parse` -- a request body -> batches (envelope: format, kind, stream);
* :mod:`.validate` -- each record on its own -> a typed row or a reason, by the
  protocol's field definitions and the columns' limits (no database);
* :mod:`.stream` -- the machine and the stream read under the machine's lock, the ack
  walk, the stream's row;
* :mod:`.dedupe` -- stored seqs of the batch: duplicates, a stream that went backwards;
* :mod:`.store` -- the batch transaction in few round trips, the COPY into ``telemetry``;
* :mod:`.progress` -- per-cell sums and job progress (also the thin profile's cells);
* :mod:`.status` and :mod:`.alerts` -- the machine's latest state, the alerts a batch
  opens or ends;
* :mod:`.live` -- the messages for the fleet view;
* :mod:`.model` -- the batch, the machine's state, the ack: the data the stages share.
"""
