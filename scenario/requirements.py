"""The requirements a fault campaign traces to its runs: a YAML file of ``requirements:`` with an id, a text and a
source each (``configs/requirements.yaml``)."""

from __future__ import annotations

from pathlib import Path

from pydantic import Field, ValidationError, field_validator

from contracts.errors import ScenarioError
from contracts.model import Config
from contracts.textfile import TextFileError, load_yaml, read_text


class Requirement(Config):
    """One requirement: its identifier, what it asks and where it comes from."""

    id: str = Field(min_length=1, pattern=r"^[A-Z0-9][A-Z0-9-]*$", description="identifier, e.g. FDIR-WHEEL")
    text: str = Field(min_length=1, description="what is required")
    source: str = Field(min_length=1, description="the document it comes from, named in full")


class Requirements(Config):
    """The file: its requirements, each id once."""

    requirements: tuple[Requirement, ...] = Field(min_length=1)

    @field_validator("requirements")
    @classmethod
    def _unique(cls, v: tuple[Requirement, ...]) -> tuple[Requirement, ...]:
        ids = [r.id for r in v]
        dup = sorted({i for i in ids if ids.count(i) > 1})
        if dup:
            raise ValueError(f"requirement ids {dup} are given twice")
        return v


def load_requirements(path: str | Path) -> Requirements:
    """Read and validate a requirements file; ScenarioError naming every problem."""
    p = Path(path)
    try:
        return Requirements.model_validate(load_yaml(read_text(p)))
    except TextFileError as exc:
        raise ScenarioError(str(p), [str(exc)]) from None
    except ValidationError as exc:
        raise ScenarioError(str(p), [f"{'.'.join(str(x) for x in e['loc'])}: {e['msg']}" for e in exc.errors()]) \
            from None
