"""The solvers' names and defaults, without the solvers' libraries.

:mod:`lf_flame.tomo.solvers` uses (and re-exports) these; the command line's argument
parser reads them from here, so ``lf-flame --help`` does not import PyLops.
"""
#: Solvers of :func:`lf_flame.tomo.solvers.reconstruct`; "adjoint" is plain refocusing (the baseline).
SOLVERS = ("adjoint", "lsqr", "fista", "pd-tv", "rl", "admm")
#: Iterations each solver runs unless told: the fewest within 10 % of the solver's best
#: worst-plane error on validation renders (``results/reconstruct_iters.csv``, ``make reconstruct``).
#: admm's: its fills on noisy data (:data:`ADMM_FILLS`; quiet data take :data:`ADMM_QUIET`'s).
ADMM_FILLS = 4
DEFAULT_ITERS = {"adjoint": 0, "lsqr": 40, "fista": 30, "pd-tv": 40, "rl": 20, "admm": ADMM_FILLS}
#: TV weight of "pd-tv" unless told (validation renders, as the iterations).
DEFAULT_TV = 0.3
#: The solver whose worst validation render is best (``make reconstruct``) on the traced operator: the default
#: of ``lf-flame reconstruct`` where the camera needs tracing (``--rays-per-pixel``, crosstalk, not a perfect grid).
DEFAULT_SOLVER = "pd-tv"
#: The default on the exact operator (every perfect lenslet grid): admm, its knobs by the data's noise, beats
#: pd-tv on every validation render (``results/fourier_solver.md``: worst plane 2.0 % on the 2 x 2 grid and 6.2 %
#: on the lenslet grid against 10.5 % noise-free, 8.1 % and 13.2 % against 18.6 % at 14 dB) in a ninth to a
#: twenty-seventh of its time (the paper's scene, ``--stage time``).
EXACT_SOLVER = "admm"
#: Knobs of the "admm" solver (:func:`lf_flame.tomo.fourier.solve_admm`), chosen on validation renders at
#: 400 rays per pixel (``experiments/exact_operator.py --stage tune``): fills of the missing data (its
#: iterations), ADMM steps per fill, the gradient weight and the penalties (relative to the stack's light
#: g0), the fills' momentum, the TV weight (absolute, as pd-tv's).
#: ``results/fourier_solver.md``: worst validation plane 13.2 % (noise-free and 14 dB) against pd-tv's 18.6 %.
ADMM_INNER = 5
ADMM_LAM = 0.03
ADMM_RHO = 0.01
#: Ridge of the learned reconstructor's Wiener start (:func:`lf_flame.tomo.fourier.wiener_start`), relative to g0:
#: on an exact render of the paper's scene its worst plane was 38 % at 1e-3 against 49 % at 1e-2 (a probe; lam 0.003-0.03
#: changed it by 2 points): the window's missing light, not the ridge, is what it leaves to the learned stage.
WIENER_RHO = 1e-3
ADMM_RHO_TV = 1.0
ADMM_MOMENTUM = 0.6
#: The fills restart (from the best fill's planes, without momentum, with ADMM_RESTART_INNER times the ADMM steps
#: per fill: an adaptive restart, O'Donoghue & Candes, Found. Comput. Math. 15 (2015)) once a fill's residual
#: exceeds ADMM_DIVERGENCE times the smallest so far. Heavy-ball momentum on inexact ADMM steps can diverge where
#: most samples are missing (a colour capture's red channel on the example camera, three quarters missing, without
#: TV: the residual grew 0.43 -> 129 over 40 fills; without momentum, 5 steps per fill, it rose from 0.33 to 0.62
#: before it came back, with 20 steps it fell monotonically). On the test suite's 81 converging solves a fill's
#: residual rose at most 1.9 times the smallest before it, so the threshold leaves such solves as they were.
ADMM_DIVERGENCE = 3.0
#: admm solves of fewer samples than this per batch of views (lit views x the FFT canvas) run on one thread,
#: Numba's and SciPy's FFT's (:func:`lf_flame.tomo.fourier.solve_threads`): there each kernel and FFT call's
#: work is shorter than waking the other threads. Measured on this project's 2-core machine (a ``/tmp`` probe of
#: ``make cameras``' decoded light fields, two scenes each noise-free and at 14 dB, median solve, two threads ->
#: one): 48 px camera (0.17 M samples) 18.2 -> 7.0 ms, example (0.17 M) 17.9 -> 11.1 ms, hexagonal (0.15 M)
#: 15.8 -> 9.9 ms, rotated (0.68 M) 60.3 -> 62.4 ms, paper (3.9 M) 185 -> 275 ms; the threshold lies between
#: 0.17 M and 0.68 M (their geometric mean).
ADMM_ONE_THREAD_SAMPLES = 340_000
ADMM_RESTART_INNER = 4
ADMM_TV = 0.3
#: admm's knobs follow the light field's noise unless told (:func:`lf_flame.tomo.noise_knobs.relative_noise`,
#: the noise's standard deviation over the views' 99.9th percentile): below :data:`ADMM_QUIET_NOISE`
#: the fills run on without TV (:data:`ADMM_QUIET`), above it :data:`ADMM_FILLS` and :data:`ADMM_TV`
#: regularise (the early-stopped fills and TV). Chosen per noise level on the validation renders
#: (``python experiments/fourier_solver.py --stage tune``: noise-free renders at 400 rays measure
#: 4e-4 to 7e-4, renders at 14 dB 0.03 to 0.04; the split lies between, the validation set holds
#: no level in between).
ADMM_QUIET_NOISE = 0.005
#: Where admm's first fill predicts the missing data from (:func:`lf_flame.tomo.fourier.solve_admm`'s ``start``),
#: and the start of the solves whose knobs are all given (the noise not measured).
ADMM_STARTS = ("zero", "refocused", "coarse")
ADMM_START = "zero"
ADMM_QUIET = {"fills": 4, "tv": 0.0}
#: admm's knobs per planes' grid (samples per lenslet footprint and axis,
#: :class:`~lf_flame.tomo.exact.ExactOperator`'s ``subsamples``) and noise level, chosen on the
#: validation renders as above (``--stage tune`` tries both grids: ``results/fourier_solver.md``).
#: The sparsity weight ``l1`` (a fraction of lambda_max) joined the grid later: it took the 2 x 2 grid's
#: worst validation plane at 14 dB from 11.4 % to 8.1 % and the lenslet grid's noise-free one from 6.2 %
#: to 6.0 %, and was not taken for the other two.
#: The start and the stopping tolerance (``solve_admm``'s ``start``, ``tol``) joined the grid later: the refocused
#: start took the quiet 2 x 2 grid's worst validation plane from 2.35 % at 11 fills to 2.04 % at 10, and its
#: tolerance stops the paper's and the varied scenes after 5-6 fills (the overlap scenes run all 10); the noisy
#: knobs keep the zero start, their tolerance stops 4 of 6 renders after 3 fills within the same score.
#: The coarse start (the lenslet grid's solve first, at its knobs here) joined later, the start then chosen by
#: the stopped solve's validation time among those within 10 % of the best score: on the quiet 2 x 2 grid
#: 2.05 % worst validation plane after 2.2 fills on average, 0.50 s median, against the refocused start's
#: 2.04 % and 0.68 s (``--stage coarse``). The same rule re-chose the lenslet grid's quiet knobs (zero start,
#: 6 fills, tol 0.02: 6.04 % and 0.22 s against the refocused start's 6.17 % and 0.20 s, within 10 % in both);
#: not taken: a tie that would change the dense stacks' results (``experiments/volume.py``) unrerun.
#: The coarse start's own start and fills cap (:data:`COARSE_KNOBS`) joined later (``--stage coarse``, 6 variants
#: at these knobs): its lenslet-grid solve from zero with up to 4 fills, then up to 5 fills on the 2 x 2 grid with
#: tol 0.02: 1.92 % worst validation plane after 3.0 fills on average, 0.32 s median, against the lenslet solve's
#: refocused start (2.05 %, 0.31 s: a tie in time, the better score taken); caps of 1 or 2 lenslet fills left the
#: fine fills more to do (2 zero-start fills: 2.09 %, 0.36 s).
#: A recording's admm (:mod:`lf_flame.recordings.job`): each chunk's frames after its first continue the previous
#: frame's solve (:func:`lf_flame.tomo.fourier.solve_admm`'s ``state``) with at most this many fills (the noise level's
#: ``tol`` may stop it after one). Chosen by a probe (not a committed command) on validation recordings of
#: ``flicker_sequence`` seed 3 (12 frames at 64 rays, the lenslet grid, the knobs of the first frame's noise:
#: the overlap at 100 frames/s, worst plane per frame against the truth): 2 fills mean 3.5 %, worst 4.1 %, against
#: solving every frame from scratch 3.8 % / 4.2 % in 0.56 of its time; 1 fill 4.0 % / 5.1 % in 0.40 (the paper's
#: flames at 500 frames/s, 1 fill: 5.2 % / 6.1 % against 5.3 % / 6.4 %). The next frame's missing data taken from
#: the last fill's prediction instead of a fresh one (a probe on the same recordings, 14 frames, overlap and
#: paper flames, noise-free and noisy): worst plane mean / p90 / worst within 0.02 points of the fresh
#: prediction's (overlap 3.44 / 3.79 / 4.10 %, paper 5.16 / 6.03 / 6.17 % noise-free), one ``H`` fewer per frame.
ADMM_STREAM_FILLS = 2
#: A recording's frame whose total light differs from the previous frame's by more than this factor (either way)
#: is solved from scratch, not continued: a dropped or black frame, a flash, a flame going out. Continued with two
#: fills, a black frame had kept the previous frame's flames (heights 5-19 mm, no failure) and a frame dimmed to
#: 0.1 six times its light on one plane. A flickering flame's frames differ by 0.90-1.16 (the simulated
#: recordings at 100 frames/s, 4-64 rays per pixel).
ADMM_STREAM_LIGHT = 1.5
ADMM_KNOBS = {(1, "quiet"): dict(ADMM_QUIET, lam=ADMM_LAM, l1=0.001, start="refocused", tol=0.05),
              (1, "noisy"): {"fills": ADMM_FILLS, "tv": ADMM_TV, "lam": ADMM_LAM, "l1": 0.0, "start": "zero", "tol": 0.05},
              (2, "quiet"): {"fills": 5, "tv": 0.0, "lam": 0.003, "l1": 0.0, "start": "coarse", "tol": 0.02},
              (2, "noisy"): {"fills": 4, "tv": 0.1, "lam": 0.01, "l1": 0.001, "start": "zero", "tol": 0.05}}
#: The coarse start's lenslet-grid solve (:func:`lf_flame.tomo.fourier.solve_admm`'s ``coarse_knobs``) per noise
#: level: the lenslet grid's knobs, its start and fills cap chosen for this role on the validation renders
#: (``python experiments/fourier_solver.py --stage coarse``: each candidate ahead of the 2 x 2 grid's quiet
#: knobs, the fastest stopped solve within 10 % of the best score, as the starts are chosen).
COARSE_KNOBS = {"quiet": dict(ADMM_KNOBS[1, "quiet"], start="zero"), "noisy": ADMM_KNOBS[1, "noisy"]}
#: admm's fills cap and stopping tolerance on an operator whose samples lie off the views' grid (a colour capture's,
#: :class:`~lf_flame.tomo.exact.ExactOperator`'s ``sample_offsets``) unless told, at both noise levels: each sample
#: is one of its view's ``M^2`` sub-views, so the fills have most of every sub-view to fill and converge more slowly
#: than on whole views. Chosen by a probe (not a committed command) on the colour camera's validation captures
#: (seeds 58101-58102 of ``experiments/cameras_colour.py``, the flames' true depths, the 2 x 2 grid, noise-free and
#: 14 dB): tol 0.005 stopped after 16-17 fills within 0.013 of 30 fills' per-plane error (tol 0.02: 12 fills, up to
#: 0.027 worse); 4 fills (the whole views' cap) left 0.30-0.37 per plane against 0.04-0.28 at 30.
OFFSET_KNOBS = {"fills": 40, "tol": 0.005}
#: The planes' grid of the routes that build their operator (``lf-flame reconstruct``,
#: :func:`lf_flame.tomo.found_planes.find_planes`): a light field carries detail finer than a lenslet in
#: its views' parallax off focus, and the 2 x 2 grid beat the lenslet grid on the validation
#: renders at both noise levels (worst plane 2.0 % against 6.2 % noise-free, 8.1 % against 13.2 %
#: at 14 dB), at 1.6-3.7 times the time per solve. Decoded views of any camera take it too: on the example
#: camera's decoded views (4 scenes of random-depth flames, ``experiments/cameras.py``'s renders) the flames'
#: errors fell from 6-9 % on the lenslet grid to 2-7 %, and on the paper camera's decoded views from 22 % to
#: 6 % at +22 mm (as its raw views give) ...
ADMM_SUBSAMPLES = 2
#: ... for stacks of at most this many planes (the per-frequency matrices grow as (P s^2)^2: at 16
#: planes on the 2 x 2 grid they are 64 x 64, some 350 MB on the paper's camera in float32)
SUBSAMPLES_MAX_PLANES = 16
#: Volumes (:func:`lf_flame.tomo.volume.solve_volume`, ``lf-flame reconstruct --volume``): the priors, the default
#: one and the plane spacing (mm). The default assumes no shape: on the non-axisymmetric validation and test
#: volumes no generic prior beat admm alone on both noise levels (``results/volume_nonaxi.md``); a laminar flame
#: takes ``axisymmetric`` (3-D error 6.4 % median against admm's 55 %, ``results/volume.md``) ...
VOLUME_PRIORS = ("none", "tv", "sparse", "axisymmetric")
VOLUME_PRIOR = "none"
VOLUME_STEP_MM = 0.5
#: ... at most this many planes (the per-frequency matrices grow as P^2: 81 planes peak at 2.2 GB on the
#: paper's camera, ``results/fourier_solver.md``) ...
VOLUME_MAX_PLANES = 81
#: ... and the weights of the "tv" and "sparse" priors per noise level (:func:`lf_flame.tomo.noise_knobs.noise_regime`),
#: chosen on 2 validation volumes by the bar score max(centroid mean / 0.3 mm, share outside the depth range / 10 %)
#: (``python experiments/volume.py --set nonaxi``, ``results/volume_nonaxi.md``; l1 a fraction of lambda_max: from
#: 0.002 up the centroids drifted 0.4-6 mm, 0.02 emptied the stack). The quiet TV weight went from 0.3 to 0.1 when
#: admm's quiet knobs took the refocused start and stopping (validation bar score 0.33 for both, 0.1 the lower).
VOLUME_TV = {"quiet": 0.1, "noisy": 1.0}
VOLUME_L1 = {"quiet": 0.0005, "noisy": 0.0005}

