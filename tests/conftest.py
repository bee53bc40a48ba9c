"""Shared fixtures."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="session")
def green_values() -> dict:
    """The verified kernel test vectors (GREEN §2.3)."""
    return json.loads((DATA / "green_values.json").read_text())
