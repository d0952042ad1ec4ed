"""``precrel``, the command line: the parser and shared options (:mod:`.program`,
:mod:`.options`) and one module per command. Commands parse, call the library and print;
no computation lives here."""

from .program import main

__all__ = ["main"]
