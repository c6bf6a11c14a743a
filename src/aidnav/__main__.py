"""``python -m aidnav``: the command-line interface."""

from aidnav.cli import main

main()
