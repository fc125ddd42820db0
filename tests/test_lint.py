"""Every Python file of the project passes ruff with the project's ruff.toml (pinned in requirements*.lock).

Unused imports, undefined names, blind excepts nobody explained and loop variables caught by closures are
bugs or hide them; checking them in make test keeps the code base clean instead of cleaning it now and then.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: the ruff of this venv (make setup installs it from the lock file), not whichever one is on PATH
RUFF = Path(sys.executable).parent / "ruff"


def test_ruff_finds_nothing() -> None:
    assert RUFF.exists(), f"{RUFF} is missing: make setup installs ruff from the lock file"
    done = subprocess.run([str(RUFF), "check", "--config", str(ROOT / "ruff.toml"), "--no-cache",
                           "--output-format", "concise", "."],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, f"ruff check found problems (exit {done.returncode}):\n{done.stdout}{done.stderr}"
