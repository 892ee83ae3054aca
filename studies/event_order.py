"""Which events limit the order of the step on the 3-D lander? The event-order study.

The study's code is :mod:`symcushion.studies.event_order` (the tests import it);
this script runs it: ``python studies/event_order.py --help``.
"""
from symcushion.studies.event_order import main

if __name__ == "__main__":
    main()
