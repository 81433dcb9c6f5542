"""Configuration from the environment, with defaults that work on a developer machine."""

from __future__ import annotations

from functools import lru_cache

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict


class Settings(BaseSettings):
    """Twelve-factor settings: every value can be overridden by an environment variable."""

    model_config = SettingsConfigDict(env_file=None, extra="ignore")

    database_url: str = Field(
        default="postgresql+psycopg://postgres@127.0.0.1:5432/fieldrx", alias="DATABASE_URL"
    )
    mqtt_url: str = Field(default="mqtt://127.0.0.1:1883", alias="MQTT_URL")
    secret_key: str = Field(default="dev-insecure-change-me", alias="SECRET_KEY")
    host: str = Field(default="127.0.0.1", alias="FIELDRX_HOST")
    port: int = Field(default=8000, alias="FIELDRX_PORT")
    token_ttl_hours: float = Field(default=24.0 * 14, alias="FIELDRX_TOKEN_TTL_HOURS")
    frontend_dist: str = Field(default="", alias="FIELDRX_FRONTEND_DIST")
    heartbeat_timeout_s: float = Field(default=30.0, alias="FIELDRX_HEARTBEAT_TIMEOUT_S")
    # Imagery (issue 14): where Cloud-Optimized GeoTIFFs live ("" = ./var/imagery beside the
    # checkout), the largest upload and raster accepted, and the conversion's time limit.
    imagery_dir: str = Field(default="", alias="FIELDRX_IMAGERY_DIR")
    imagery_max_upload_bytes: int = Field(
        default=4 * 1024**3, alias="FIELDRX_IMAGERY_MAX_UPLOAD_BYTES"
    )
    imagery_max_pixels: int = Field(default=2_000_000_000, alias="FIELDRX_IMAGERY_MAX_PIXELS")
    imagery_timeout_s: float = Field(default=900.0, alias="FIELDRX_IMAGERY_TIMEOUT_S")


@lru_cache
def get_settings() -> Settings:
    return Settings()
