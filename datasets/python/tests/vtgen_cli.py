"""Running the Rust ``vtgen`` binary from the tests (used by ``conftest.py`` and test modules)."""

from __future__ import annotations

import subprocess
from pathlib import Path
from typing import List

import pytest

# tests/ -> python/ -> datasets/ -> repository root
REPO_ROOT = Path(__file__).resolve().parents[3]
SCENES = REPO_ROOT / "scenes"


def run(args: List[str], timeout: float) -> subprocess.CompletedProcess:
    """Run a command; on a non-zero exit fail the test with the tail of its output."""
    result = subprocess.run(args, capture_output=True, text=True, timeout=timeout)
    if result.returncode != 0:
        pytest.fail(
            f"command failed with exit status {result.returncode}: {' '.join(args)}\n"
            f"--- stdout ---\n{result.stdout[-4000:]}\n--- stderr ---\n{result.stderr[-4000:]}",
            pytrace=False,
        )
    return result
