"""Which events limit the order of the step on the 3-D lander? The event-order study.

The study's code is the research package ``research/event_order/`` (the
tests import it; it is not installed with symcushion); this script runs it:
``python studies/event_order.py --help``. Findings: docs/event-order.md.
"""
import sys
from pathlib import Path

# research/ is not installed: import it from this checkout, whatever the working directory.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from research.event_order import main  # noqa: E402 - needs the path above

if __name__ == "__main__":
    main()
