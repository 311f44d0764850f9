"""``python -m inertia_ros``: the offline command-line interface."""
import sys

from inertia_ros.cli import main

if __name__ == '__main__':
    sys.exit(main())
