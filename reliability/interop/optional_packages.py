"""Importing an optional package of the ``interop`` extra, or saying how to install it."""

from __future__ import annotations

import importlib

#: The extra that installs OpenTURNS and SALib.
INSTALL_HINT = 'pip install "precision-reliability[interop]" (or pip install -e ".[interop]")'


def optional_import(module: str, package: str):
    """Import ``module`` (of the distribution ``package``), or raise an ImportError that
    names the ``interop`` extra to install."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise ImportError(f"reliability.interop needs {package}, which is not installed; "
                          f"install the 'interop' extra: {INSTALL_HINT}") from None
