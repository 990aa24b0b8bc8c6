"""``python -m sonar_embree``: the command line (:mod:`sonar_embree.runs.cli`)."""
import sys

from .runs.cli import main

if __name__ == "__main__":      # importing the module (the API reference does) runs nothing
    sys.exit(main())
