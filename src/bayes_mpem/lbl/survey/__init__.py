"""The per-survey commands."""
