"""Hard-case battery: does each contact method survive the cases that break simulators?

The study's code is :mod:`symcushion.studies.hard_cases` (the tests import it);
this script runs it: ``python studies/hard_cases.py --help``.
"""
from symcushion.studies.hard_cases import main

if __name__ == "__main__":
    main()
