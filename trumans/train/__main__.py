"""`python -m trumans.train` (also under `torchrun --nproc_per_node N -m trumans.train ...`)."""
import sys

from trumans.train.cli import main

sys.exit(main())
