"""`python -m augment` = `trumans augment`."""
import sys

from trumans.cli import main

if __name__ == "__main__":
    sys.exit(main(["augment", *sys.argv[1:]]))
