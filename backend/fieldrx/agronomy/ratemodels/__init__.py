"""Rate models, one class per module, listed by ``registry.RATE_MODELS``."""
