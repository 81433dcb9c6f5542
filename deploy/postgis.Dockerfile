# The database of docker-compose.yml: PostGIS plus pg_partman, which keeps telemetry's
# daily partitions (migration 0010_telemetry_partitions, fieldrx.fleet.partitions).
# The image's PGDG apt source serves pg_partman 5; Debian 12 (scripts/setup.sh) serves
# 4.7; fieldrx speaks both.
FROM postgis/postgis:15-3.4
RUN apt-get update \
    && apt-get install -y --no-install-recommends postgresql-15-partman \
    && rm -rf /var/lib/apt/lists/*
