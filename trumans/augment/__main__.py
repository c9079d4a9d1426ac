"""`python -m trumans.augment` = `trumans augment`."""
import sys

from trumans.cli import console_main

if __name__ == "__main__":
    sys.exit(console_main(["augment", *sys.argv[1:]]))
