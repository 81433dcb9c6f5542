"""FieldRx edge agent: everything that runs on the tractor, and the wire protocol.

It never imports the server (``fieldrx``); the server imports a few of its pure modules.
Map: docs/architecture.md ("Edge agent") and docs/edge.md; equations: docs/science.md.
"""
