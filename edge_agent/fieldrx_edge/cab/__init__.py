"""The operator's cab display, served by the agent itself (no network needed)."""
