"""Thesis experiments, one module per chapter: functions that return `Result` objects (no plotting)."""
