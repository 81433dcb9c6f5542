"""Users, organisations, API tokens, device tokens and roles."""
