"""Common error type for user mistakes (bad scene, camera, size, file): one-line messages.

Every error a user can cause by what they typed or which file they pointed at is a
``RayflexError`` (a ``ValueError``), so callers can catch ``ValueError`` and print one line.
``driver.BackendError`` (unknown backend, backend that cannot be built) is a ``ValueError`` too.
"""

from __future__ import annotations


class RayflexError(ValueError):
    """A user-level mistake; the message is one line and names the offending input."""


class SceneError(RayflexError):
    """Unknown scene, missing/unreadable/unsupported mesh file, invalid mesh or scene TOML."""


class CameraError(RayflexError):
    """Invalid camera (fov, position == look_at, up parallel to the view, non-finite) or size."""


class Terminated(BaseException):
    """SIGTERM arrived while work that must clean up ran (a model build; the command line):
    raised by the signal handler so ``finally`` blocks and process-group kills run."""
