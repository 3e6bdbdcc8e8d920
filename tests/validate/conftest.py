"""Fixtures of the validation tests: one small atlas with every LUT model type, baked once."""

from __future__ import annotations

from tests.validate.validation_fixtures import mitsuba_rgb, validation_atlas, validation_run  # noqa: F401
