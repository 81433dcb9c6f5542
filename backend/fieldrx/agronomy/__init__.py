"""Agronomy: soil samples, interpolation onto cells, rate models, prescriptions (pure, no DB)."""
