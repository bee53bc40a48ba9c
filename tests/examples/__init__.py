"""Test-only extensions, each one module plus one registry entry, that the shared suite runs
as it runs the package's own (docs/extending.md): registered by ``tests/conftest.py``."""
