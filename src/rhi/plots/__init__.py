"""Matplotlib figures drawn from experiment result objects (no computation here)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")  # headless by default; figures are saved, not shown
