"""One module per CLI command: ``<name>_cmd.py`` with ``add_parser`` and ``run``."""
