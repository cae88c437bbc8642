"""Provenance: what produced a JSON document (the ``provenance`` object every command writes,
docs/statistics.md): the rayflex version, the git commit of the source tree, the design point and
the machine."""

from __future__ import annotations

import os
import platform
import subprocess
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np

from .resources import checkout


def provenance(point=None) -> dict:
    """The ``provenance`` object of every JSON the commands write: the rayflex version, the git
    commit of the source tree when it is a git checkout (None for an installed wheel), the whole
    design point (``driver.design.DesignPoint``; None when there is none) and the machine."""
    dp = None
    if point is not None:
        dp = point.as_dict()
        if hasattr(point, "clock"):          # the clock as resolved, and where it came from
            dp["clock_mhz"], dp["clock_source"] = point.clock()
    return {"rayflex_version": rayflex_version(), "git_commit": git_commit(),
            "design_point": dp, "machine": machine()}


def rayflex_version() -> str | None:
    try:
        return version("rayflex-driver")
    except PackageNotFoundError:
        return None


def git_commit() -> str | None:
    """HEAD of the git checkout holding this package (None when it is not in one)."""
    root = checkout()
    if root is None or not (root / ".git").exists():
        return None
    try:
        out = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True,
                             text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    commit = out.stdout.strip()
    return commit if out.returncode == 0 and len(commit) == 40 else None


def machine() -> dict:
    """CPU model (first ``model name`` of /proc/cpuinfo), logical cores (all / usable)."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        usable = os.cpu_count()
    return {"cpu": cpu, "cores": os.cpu_count(), "cores_usable": usable,
            "python": platform.python_version(), "numpy": np.__version__,
            "platform": platform.platform()}
