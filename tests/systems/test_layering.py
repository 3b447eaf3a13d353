"""The layering rules themselves are import-linter contracts (``[tool.importlinter]`` in
pyproject.toml), checked by ``lint-imports`` in ``make test``: statically, over every
module, imports inside functions included. This file only guards those contracts against
passing vacuously.
"""

from __future__ import annotations

import importlib.util
import tomllib
from pathlib import Path

PYPROJECT = Path(__file__).resolve().parents[2] / "pyproject.toml"
MODULE_LISTS = ("source_modules", "forbidden_modules", "protected_modules", "allowed_importers")


def test_contracts_name_installed_external_packages():
    """import-linter stops on an internal module that does not exist, but a misspelled
    external one (``PySide`` for ``PySide6``) matches no import and its contract is KEPT."""
    config = tomllib.loads(PYPROJECT.read_text())["tool"]["importlinter"]
    roots = set(config["root_packages"])
    external = {
        name
        for contract in config["contracts"]
        for key in MODULE_LISTS
        for name in contract.get(key, ())
        if name.split(".")[0] not in roots
    }
    assert external  # PySide6 and pyqtgraph, forbidden in systems
    missing = sorted(name for name in external if importlib.util.find_spec(name) is None)
    assert missing == [], f"import-linter contracts name packages that are not installed: {missing}"
