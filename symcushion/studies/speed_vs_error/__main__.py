"""``python -m symcushion.studies.speed_vs_error``: the same as ``studies/speed_vs_error.py``."""
import sys

from .main import main

main(sys.argv[1:])
