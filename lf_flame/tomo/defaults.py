"""The solvers' names and defaults, without the solvers' libraries.

:mod:`lf_flame.tomo.solvers` uses (and re-exports) these; the command line's argument
parser reads them from here, so ``lf-flame --help`` does not import PyLops.
"""
#: Solvers of :func:`lf_flame.tomo.solvers.reconstruct`; "adjoint" is plain refocusing (the baseline).
SOLVERS = ("adjoint", "lsqr", "fista", "pd-tv", "rl", "admm")
#: Iterations each solver runs unless told: the fewest within 10 % of the solver's best
#: worst-plane error on validation renders (``results/reconstruct_iters.csv``, ``make reconstruct``).
DEFAULT_ITERS = {"adjoint": 0, "lsqr": 40, "fista": 30, "pd-tv": 40, "rl": 20, "admm": 4}
#: TV weight of "pd-tv" unless told (validation renders, as the iterations).
DEFAULT_TV = 0.3
#: The solver whose worst validation render is best (``make reconstruct``): the default of ``lf-flame reconstruct``.
DEFAULT_SOLVER = "pd-tv"
#: Knobs of the "admm" solver (:func:`lf_flame.tomo.fourier.solve_admm`), chosen on validation renders at
#: 400 rays per pixel (``experiments/exact_operator.py --stage tune``): fills of the missing data (its
#: iterations), ADMM steps per fill, the gradient weight and the penalties (relative to the stack's light
#: g0), the fills' momentum, the TV weight (absolute, as pd-tv's).
#: ``results/fourier_solver.md``: worst validation plane 13.2 % (noise-free and 14 dB) against pd-tv's 18.6 %.
ADMM_FILLS = 4
ADMM_INNER = 5
ADMM_LAM = 0.03
ADMM_RHO = 0.01
ADMM_RHO_TV = 1.0
ADMM_MOMENTUM = 0.6
ADMM_TV = 0.3
