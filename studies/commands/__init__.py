"""Subcommands of ``precrel``: one module each, with ``add_parser`` and ``run``."""
