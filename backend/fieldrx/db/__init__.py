"""Database access: engine, sessions and ORM models (PostGIS through GeoAlchemy2)."""
