"""Study code that the tests exercise: the hard-case battery and the speed-vs-error study.

The scripts ``studies/hard_cases.py`` and ``studies/speed_vs_error.py`` run
these subpackages' ``main()``; the code lives in the package so that the tests
import it like any other module instead of from ``sys.path``. This package
only holds study drivers; it must not define physics of its own.
"""
