"""Research that answers a question about the package, kept out of it.

Each subpackage is a study whose findings are a page of ``docs/``; the
installed ``symcushion`` holds only what a user calls and never imports
from here. Nothing here is installed: the scripts in ``studies/`` and the
tests put the repository root on ``sys.path`` to import it (see
``tests/conftest.py``).
"""
