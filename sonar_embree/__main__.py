"""``python -m sonar_embree``: the command line (:mod:`sonar_embree.runs.cli`)."""
import sys

from .runs.cli import main

sys.exit(main())
