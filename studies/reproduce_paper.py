"""``python -m studies.reproduce_paper``: the paper's case study into ``figures/``.

The stable entry point of :mod:`studies.paper.reproduce`, which holds the study itself.
"""

import sys

from .paper.reproduce import main

if __name__ == "__main__":
    sys.exit(main())
