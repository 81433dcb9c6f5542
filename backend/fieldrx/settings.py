"""Configuration from the environment, with defaults that work on a developer machine."""

from __future__ import annotations

from functools import lru_cache
from typing import Literal

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict


class Settings(BaseSettings):
    """Twelve-factor settings: every value can be overridden by an environment variable."""

    model_config = SettingsConfigDict(env_file=None, extra="ignore")

    database_url: str = Field(
        default="postgresql+psycopg://postgres@127.0.0.1:5432/fieldrx", alias="DATABASE_URL"
    )
    # the project's own broker (deploy/mosquitto.conf); user-info, if any, is the worker's
    mqtt_url: str = Field(default="mqtt://127.0.0.1:1884", alias="MQTT_URL")
    mqtt_ca_file: str = Field(default="", alias="MQTT_CA_FILE")
    # "dynsec": device tokens get broker credentials; "off": HTTP-only deployments
    mqtt_credentials: Literal["dynsec", "off"] = Field(
        default="dynsec", alias="FIELDRX_MQTT_CREDENTIALS"
    )
    # ingest workers: persistent MQTT sessions per stable slot (fleet/worker.py)
    worker_session_expiry_s: int = Field(
        default=3600, ge=0, alias="FIELDRX_WORKER_SESSION_EXPIRY_S"
    )
    worker_node: str = Field(default="", alias="FIELDRX_WORKER_NODE")
    worker_slot_dir: str = Field(default="", alias="FIELDRX_WORKER_SLOT_DIR")
    # database connections (lanes) per ingest worker: batches of different machines commit
    # at once (fleet/worker.py); 1: on one 2-core host more lanes only added contention
    # (docs/scale.md section 5 for the measurements)
    worker_db_connections: int = Field(default=1, ge=1, alias="FIELDRX_WORKER_DB_CONNECTIONS")
    secret_key: str = Field(default="dev-insecure-change-me", alias="SECRET_KEY")
    host: str = Field(default="127.0.0.1", alias="FIELDRX_HOST")
    port: int = Field(default=8000, alias="FIELDRX_PORT")
    token_ttl_hours: float = Field(default=24.0 * 14, alias="FIELDRX_TOKEN_TTL_HOURS")
    frontend_dist: str = Field(default="", alias="FIELDRX_FRONTEND_DIST")
    heartbeat_timeout_s: float = Field(default=30.0, alias="FIELDRX_HEARTBEAT_TIMEOUT_S")
    # hardening: cost bounds of one request (services.bounded, app middleware)
    heavy_workers: int = Field(default=2, alias="FIELDRX_HEAVY_WORKERS")
    plan_time_limit_s: float = Field(default=120.0, alias="FIELDRX_PLAN_TIME_LIMIT_S")
    import_time_limit_s: float = Field(default=60.0, alias="FIELDRX_IMPORT_TIME_LIMIT_S")
    max_body_bytes: int = Field(default=16 * 1024 * 1024, alias="FIELDRX_MAX_BODY_BYTES")
    max_upload_bytes: int = Field(default=51 * 1024 * 1024, alias="FIELDRX_MAX_UPLOAD_BYTES")
    login_max_failures_account: int = Field(default=10, alias="FIELDRX_LOGIN_MAX_FAILURES")
    login_max_failures_ip: int = Field(default=100, alias="FIELDRX_LOGIN_MAX_FAILURES_IP")
    login_window_s: float = Field(default=900.0, alias="FIELDRX_LOGIN_WINDOW_S")
    # progressive delay per account + address: after this many failures in the window the
    # next attempt waits base, then 2 x base, 4 x base ... (at most 60 s) after the last one
    login_delay_after: int = Field(default=3, ge=0, alias="FIELDRX_LOGIN_DELAY_AFTER")
    login_delay_base_s: float = Field(default=1.0, ge=0, alias="FIELDRX_LOGIN_DELAY_BASE_S")
    live_token_check_s: float = Field(default=5.0, alias="FIELDRX_LIVE_TOKEN_CHECK_S")
    device_token_ttl_days: float = Field(default=365.0, alias="FIELDRX_DEVICE_TOKEN_TTL_DAYS")
    # task workers remove expired devices' broker users at each expiry and at least this
    # often (tasks.worker.expire_device_credentials)
    device_expiry_check_s: float = Field(default=60.0, gt=0, alias="FIELDRX_DEVICE_EXPIRY_CHECK_S")
    # Imagery: where Cloud-Optimized GeoTIFFs live ("" = ./var/imagery beside the
    # checkout), the largest upload and raster accepted, and the conversion's time limit.
    imagery_dir: str = Field(default="", alias="FIELDRX_IMAGERY_DIR")
    imagery_max_upload_bytes: int = Field(
        default=4 * 1024**3, alias="FIELDRX_IMAGERY_MAX_UPLOAD_BYTES"
    )
    imagery_max_pixels: int = Field(default=2_000_000_000, alias="FIELDRX_IMAGERY_MAX_PIXELS")
    imagery_timeout_s: float = Field(default=900.0, alias="FIELDRX_IMAGERY_TIMEOUT_S")
    # conversion budget: a raster declaring more uncompressed bytes than this many times
    # its file size is refused before decoding (imagery.ingest._check_budget)
    imagery_max_expansion: float = Field(default=400.0, gt=1, alias="FIELDRX_IMAGERY_MAX_EXPANSION")
    # Thin uplink: where the 10 Hz logs tractors upload on request live
    # ("" = ./var/rawlogs beside the checkout), and the largest accepted (gzip bytes).
    raw_log_dir: str = Field(default="", alias="FIELDRX_RAW_LOG_DIR")
    raw_log_max_bytes: int = Field(default=512 * 1024**2, alias="FIELDRX_RAW_LOG_MAX_BYTES")
    # Telemetry partitions (fleet.partitions): raw records older than this many
    # days are dropped a whole day at a time (0: kept forever); per-cell results are kept.
    telemetry_retention_days: int = Field(default=0, ge=0, alias="FIELDRX_TELEMETRY_RETENTION_DAYS")
    # how often each `fieldrx worker` runs partition maintenance (premake, retention, moving
    # rows out of the default partition); 0: never (run `fieldrx telemetry-maintenance`)
    telemetry_maintenance_s: float = Field(
        default=3600.0, ge=0, alias="FIELDRX_TELEMETRY_MAINTENANCE_S"
    )
    # uploads larger than this are converted by a task worker (202 + task) instead of inline
    imagery_background_bytes: int = Field(
        default=64 * 1024**2, ge=0, alias="FIELDRX_IMAGERY_BACKGROUND_BYTES"
    )
    # A confirmed ISOXML import whose upload is larger than this runs as a background
    # task (202 + task) instead of inside the request: planning its grids takes seconds.
    import_background_bytes: int = Field(
        default=4 * 1024**2, ge=0, alias="FIELDRX_IMPORT_BACKGROUND_BYTES"
    )
    # Background tasks (fieldrx.tasks): jobs run at once per worker process, how
    # often a worker proves it is alive, and after how long without a heartbeat its running
    # jobs are handed to another worker (stalled-job recovery).
    task_concurrency: int = Field(default=2, ge=1, alias="FIELDRX_TASK_CONCURRENCY")
    # an organisation's open (queued + running) tasks at most: more get 429 + Retry-After
    task_quota: int = Field(default=200, ge=1, alias="FIELDRX_TASK_QUOTA")
    task_heartbeat_s: float = Field(default=10.0, gt=0, alias="FIELDRX_TASK_HEARTBEAT_S")
    task_stalled_after_s: float = Field(default=60.0, gt=0, alias="FIELDRX_TASK_STALLED_AFTER_S")
    # Files tasks produce (exports, job-report snapshots; tasks.files) are deleted this long
    # after they were written, checked by every task worker every task_result_purge_s.
    task_result_retention_s: float = Field(
        default=24 * 3600.0, gt=0, alias="FIELDRX_TASK_RESULT_RETENTION_S"
    )
    task_result_purge_s: float = Field(default=600.0, gt=0, alias="FIELDRX_TASK_RESULT_PURGE_S")
    # a job report or as-applied export over this many records runs as a task (202) unless
    # the request says background=false; a prescription export over this many cells too
    report_background_records: int = Field(
        default=50_000, ge=0, alias="FIELDRX_REPORT_BACKGROUND_RECORDS"
    )
    export_background_cells: int = Field(
        default=100_000, ge=0, alias="FIELDRX_EXPORT_BACKGROUND_CELLS"
    )
    # an export or job-report task runs in a heavy-work child at most this long
    export_time_limit_s: float = Field(default=900.0, gt=0, alias="FIELDRX_EXPORT_TIME_LIMIT_S")


@lru_cache
def get_settings() -> Settings:
    return Settings()
