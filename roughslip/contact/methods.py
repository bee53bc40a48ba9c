"""The registry of solution methods lives in :mod:`roughslip.registry`; this name is kept for
code written against earlier versions."""

from roughslip.registry import Registry

__all__ = ["Registry"]
