"""Base class of every message and config: immutable, typed, no unknown fields."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class Frozen(BaseModel):
    """An immutable pydantic model that forbids fields it does not declare."""

    model_config = ConfigDict(frozen=True, extra="forbid")
