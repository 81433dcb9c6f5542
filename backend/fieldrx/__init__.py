"""FieldRx server.

The map of its packages, the direction imports may flow and a job's data flow are in
docs/architecture.md; the papers' equations and their errata in docs/science.md; running
past one database node in docs/scale.md.
"""

__version__ = "0.1.0"
