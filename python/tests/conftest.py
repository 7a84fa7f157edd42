"""Shared fixtures: the repository's paths and the command-line binary."""

import os
import pathlib
import shutil

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
ROOM = ROOT / "scenes" / "room.toml"


@pytest.fixture(scope="session")
def whitted_bin() -> str:
    """The `whitted` binary: $WHITTED_BIN, else target/{release,debug}/whitted. The
    comparisons with the command line must not be skipped silently, so its absence fails."""
    env = os.environ.get("WHITTED_BIN")
    candidates = [env] if env else [ROOT / "target" / d / "whitted" for d in ("release", "debug")]
    for c in candidates:
        if c and os.path.isfile(c):
            return str(c)
    found = shutil.which("whitted")
    if found:
        return found
    pytest.fail(f"no whitted binary (tried {candidates}); build it with `cargo build` or set WHITTED_BIN")
