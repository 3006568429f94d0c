"""The error of an unusable configuration value: one type, raised by every parse-time check.

Defined at the bottom of the library so the planner (:mod:`brdfpipe.plan`)
and the specs' own checks (:func:`brdfpipe.registry.manifold.check_paths`) raise
the same exception, which the Snakefile and the command line turn into one
line naming the key.
"""

from __future__ import annotations

__all__ = ["ConfigError"]


class ConfigError(ValueError):
    """A configuration value is unusable; the message names the key."""
