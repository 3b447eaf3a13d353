"""Headless physics for Phase Explorer: parsing, derivation, compilation, integration.

This package never imports Qt or ``explorer`` (checked by ``tests/systems/test_layering.py``).
"""
