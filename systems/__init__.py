"""Headless physics for Phase Explorer: parsing, derivation, compilation, integration.

This package never imports Qt or ``explorer`` (import-linter's contracts in
``pyproject.toml``, run by ``make test``).
"""
