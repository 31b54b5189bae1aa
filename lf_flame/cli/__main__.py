"""``python -m lf_flame.cli``: the same as ``lf-flame``."""
import sys

from . import main

sys.exit(main())
