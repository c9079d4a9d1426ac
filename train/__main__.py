"""`python -m train` (also under `torchrun --nproc_per_node N -m train ...`)."""
import sys

from .cli import main

sys.exit(main())
