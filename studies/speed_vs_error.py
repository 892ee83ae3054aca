"""How much accuracy does a second of computing buy? The speed-vs-error study.

The study's code is :mod:`symcushion.studies.speed_vs_error` (the tests import it);
this script runs it: ``python studies/speed_vs_error.py --help``.
"""
from symcushion.studies.speed_vs_error import main

if __name__ == "__main__":
    main()
