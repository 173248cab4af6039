"""The base of every config section: unknown keys are errors, assignments are validated, and
every number must be finite (``.inf`` or ``1e400`` in a YAML file is an error, not a value)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class Section(BaseModel):
    model_config = ConfigDict(extra="forbid", validate_assignment=True, allow_inf_nan=False)
