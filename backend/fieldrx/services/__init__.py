"""DB-heavy services behind the API routers (COPY, PostGIS queries); handlers stay thin."""
