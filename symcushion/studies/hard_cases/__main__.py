"""``python -m symcushion.studies.hard_cases``: the same as ``studies/hard_cases.py``."""
from .main import main

main()
