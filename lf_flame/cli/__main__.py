"""``python -m lf_flame.cli``: the same as ``lf-flame``."""
from . import run

run()
