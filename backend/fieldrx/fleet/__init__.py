"""Fleet: telemetry ingest (HTTP and MQTT), live fan-out, alerts and as-applied reports."""
