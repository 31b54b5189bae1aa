# lf_flame: `make tables` reproduces the paper's Tables I and II; `make test` runs the tests.
# PRESET=paper (default) or PRESET=quick (same code, tiny sizes, minutes).
PRESET ?= paper
.SECONDEXPANSION:
PYTHON ?= python3
VENV := .venv
STAMP := $(VENV)/.installed
LF := $(VENV)/bin/lf-flame
DATA := data/$(PRESET)
MODELS := models/$(PRESET)
RES := results/$(PRESET)
DCFG := data_gen/$(PRESET).toml
ECFG := experiments/$(PRESET).toml
# Scene regimes (docs/scenes.md): 'paper' varies only what the paper states (Tables I and II
# beside the paper), 'varied' also position, size, rotation, radiance and flicker.
REGIMES := paper varied
SCENES := shapes flame
# a second held-out set scored beside the test split: samples drawn like the dataset's but from
# their own seed, which no dataset, training or choice uses (never stored, never seen)
HELDOUT_paper := 20
HELDOUT_quick := 4
HELDOUT_SEED := 770077

.PHONY: train-reconstructor cameras defects clipping floor one-command thread-wait temperature temperature-volume temperature-sequence help install docs dataset bench-sim bench-refocus real-data real-found train-shapes train-flame tables tradeoff reconstruct resolution depth volume volume-nonaxi volume-edge volume-search sequence new-user guide-temperature heights test clean-quick
.DEFAULT_GOAL := help

help: ## list the targets
	@grep -E '^[a-z-]+:.*## ' $(MAKEFILE_LIST) | awk -F':.*## ' '{printf "  %-14s %s\n", $$1, $$2}'
	@echo "  PRESET=paper|quick (now: $(PRESET)); outputs: DATA=, MODELS=, RES= (data/, models/, results/ of the preset)"

$(STAMP): setup.cfg pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(VENV)/bin/pip install --upgrade pip
	$(VENV)/bin/pip install -e ".[test]"
	touch $@

install: $(STAMP) ## create .venv and install the package (once)

# the documentation site (mkdocs.yml, docs/): its tools are the package's `docs` extra, installed
# into .venv once; the build is offline and fails on any warning (broken link, missing page)
DOCS_STAMP := $(VENV)/.docs-installed
$(DOCS_STAMP): setup.cfg | $(STAMP)
	$(VENV)/bin/pip install -e ".[docs]"
	touch $@

docs: $(DOCS_STAMP) ## build the documentation site into site/ (mkdocs build --strict; installs the docs extra once)
	$(VENV)/bin/mkdocs build --strict

# The installed package is an order-only prerequisite: reinstalling it does not invalidate data.
$(DATA)/slopes.json: $(DCFG) | $(STAMP)
	$(LF) slopes --data-config $(DCFG) --out $@ --results $(RES)

# the stem is REGIME/SCENE: $(*D) is the regime, $(*F) the scene
$(DATA)/%.h5: $(DATA)/slopes.json $(DCFG)
	$(LF) dataset --data-config $(DCFG) --regime $(*D) --scene $(*F) --slopes $< --out $@

ifdef SHARD
dataset: $(DATA)/slopes.json  # with SHARD=i/N: shard i of N of each dataset
	$(foreach r,$(REGIMES),$(foreach s,$(SCENES),$(LF) dataset --data-config $(DCFG) --regime $(r) --scene $(s) \
		--slopes $< --out $(DATA)/$(r)/$(s).h5 --shard $(SHARD) &&)) true
else
dataset: $(foreach r,$(REGIMES),$(foreach s,$(SCENES),$(DATA)/$(r)/$(s).h5)) ## render the datasets of both regimes (resumable; SHARD=i/N renders shard i of N)
endif

temperature: $(STAMP) ## two-colour pyrometry with a colour (Bayer) light-field camera -> results/temperature{,_behind}.{csv,md,json}, results/temperature_calibration.json
	$(VENV)/bin/python experiments/temperature.py --out results --stage flames $(if $(filter quick,$(PRESET)),--quick,)
	$(VENV)/bin/python experiments/temperature.py --out results --stage behind $(if $(filter quick,$(PRESET)),--quick,)

# temperature of a recording's planes over time: the paper's four flames flickering in colour, each
# frame through the shipped route at 14 and 20 dB, against the truth; uses make temperature's calibration
temperature-sequence: $(STAMP) ## temperature of a flickering recording's planes over time -> results/temperature_sequence.{csv,md,json,png}
	$(VENV)/bin/python experiments/temperature_sequence.py $(if $(filter quick,$(PRESET)),--out results/quick --quick,--out results)

# two-colour temperature per voxel of axisymmetric colour flames: each channel's e(r, y) on its
# own CFA samples, unmatched and matched (re-solved on the other channel's), the ratio to T; renders cached in
# data/temperature_volume
temperature-volume: $(STAMP) ## temperature per voxel of axisymmetric flames -> results/temperature_volume.{csv,md,json,png}
	$(VENV)/bin/python experiments/temperature_volume.py --out $(if $(filter quick,$(PRESET)),results/quick --quick,results)

bench-sim: $(STAMP) ## simulator benchmark -> results/bench_sim.{csv,md,json}
	$(VENV)/bin/python experiments/bench_sim.py --out results

PCAM := .bench/plenopticam
$(PCAM)/.installed: $(STAMP)
	@# PlenoptiCam is a benchmark baseline only; its registry dependencies would downgrade
	@# scikit-image and matplotlib, so it goes into its own folder without them (NOTES.md)
	$(VENV)/bin/pip install -q --no-deps --target $(PCAM) plenopticam==0.9.3 color-space-converter==0.1.4 \
		color-matcher==0.6.0 depthy==0.4.0 || echo "PlenoptiCam not installed: the benchmark runs without it"
	mkdir -p $(PCAM) && touch $@

bench-refocus: $(STAMP) $(PCAM)/.installed ## refocusing benchmark -> results/bench_refocus.{csv,md,json}
	$(VENV)/bin/python experiments/bench_refocus.py --out results --plenopticam $(PCAM)

NLF := .bench/napari-lf
$(NLF)/.installed: $(STAMP)
	@# napari-lf's three example captures (real light-field microscopy, BSD-3) are a data source only:
	@# the package would bring napari and Qt, so it goes into its own folder without them and lf_flame
	@# never imports it (experiments/real_captures.py reads its napari_lf/examples files)
	$(VENV)/bin/pip install -q --no-deps --target $(NLF) napari-lf==0.1.7 || echo "napari-lf not installed: the real-data steps are skipped"
	mkdir -p $(NLF) && touch $@

real-data: $(STAMP) $(NLF)/.installed $(PCAM)/.installed ## calibrate, decode and refocus napari-lf's real captures -> results/real/
	$(VENV)/bin/python experiments/real_captures.py --data $(NLF)/napari_lf/examples --out results/real --plenopticam $(PCAM)

real-found: $(STAMP) $(NLF)/.installed ## napari-lf's real captures through depth finding and the default reconstruction -> results/real/found.{csv,md,json}
	$(VENV)/bin/python experiments/real_found.py --data $(NLF)/napari_lf/examples --out results/real

defects: $(STAMP) ## a sensor's hot and dead pixels: depths found and planes as they are and repaired -> results/defects.{csv,md,json}
	$(VENV)/bin/python experiments/defects.py --out results

clipping: $(STAMP) ## a sensor's clipping level in 16-bit files of 12-bit counts: the type's level and the level found -> results/clipping.{csv,md,json,png}
	$(VENV)/bin/python experiments/clipping.py --out results

# Wall time and peak memory of each training target, from GNU time where the machine has it: each run's report
# appended (a resumed run's time adds to the first's, not in its place).
TIMEV = $(if $(wildcard /usr/bin/time),/usr/bin/time -v -a -o $(@D)/time_v.txt,)

$(MODELS)/%/train_info.json: $(DATA)/%.h5 $(ECFG)
	mkdir -p $(@D)
	$(TIMEV) $(LF) train --dataset $< --experiment-config $(ECFG) --out $(@D)

train-shapes: $(foreach r,$(REGIMES),$(MODELS)/$(r)/shapes/train_info.json) ## train the model (and its baselines) on the shapes
train-flame: $(foreach r,$(REGIMES),$(MODELS)/$(r)/flame/train_info.json) ## train the model (and its baselines) on the flames

# flame height, base and centre measured on the ground-truth planes (test split) against the simulation's truth
heights: $(foreach r,$(REGIMES),$(RES)/$(r)/heights_gt.csv) ## flame diagnostics on the ground truth -> results/PRESET/REGIME/heights_gt.csv

$(RES)/%/heights_gt.csv: $(DATA)/%/flame.h5 experiments/flame_heights.py lf_flame/measure/diagnostics.py
	$(VENV)/bin/python experiments/flame_heights.py --dataset $< --out $(@D)

# the paper preset's map is committed in results/, the quick one stays in results/quick
TRADEOFF_OUT := $(if $(filter paper,$(PRESET)),results,$(RES))
# timed calls per route after the warm-up (latency median, p10, p90); `make tradeoff REPEATS=3` for a quicker map
REPEATS := 20
tradeoff: $(MODELS)/varied/flame/train_info.json ## speed-accuracy map of every route and knob -> results/tradeoff.{csv,md,png}
	$(VENV)/bin/python experiments/tradeoff.py --preset $(PRESET) --data-dir $(DATA)/varied \
		--model-dir $(MODELS)/varied --out $(TRADEOFF_OUT) --repeats $(REPEATS)

# each plane's emission from one light field (lf_flame.tomo), scored against the truth; the
# paper preset's results are committed in results/, the quick one (fewer renders) stays in results/quick
RECON_ARGS_paper := --tests 2 --tail 200
RECON_ARGS_quick := --tests 1 --tail 8
DEPTH_ARGS_quick := --quick
# flame recordings over time (lf_flame.recordings): each plane's flicker frequency, the overlap, and the
# per-frame cost serially and on Dask; `--stage reconstruct` (about 30 min) adds the overlap's emission route
sequence: $(STAMP) ## flame recordings: per-plane flicker spectra, serial and Dask frames/s, admm frame after frame -> results/sequence{,_stream}.{csv,md,json,png}
	$(VENV)/bin/python experiments/sequence.py --out $(TRADEOFF_OUT)
	$(VENV)/bin/python experiments/sequence.py --out $(TRADEOFF_OUT) --stage stream

# a new user's first light field through the command line (the README quick start's simulate, then profiles per route)
new-user: $(STAMP) ## the README's quick start, each command timed, each profiles route's heights -> results/new_user.{csv,md}
	$(VENV)/bin/python experiments/new_user.py --out $(TRADEOFF_OUT)

guide-temperature: $(STAMP) ## the temperature guide's colour recording, each command timed, each plane against its flame's sheath -> results/guide_temperature.{csv,md}
	$(VENV)/bin/python experiments/guide_temperature.py --out $(TRADEOFF_OUT)

reconstruct: $(STAMP) ## 3-D emission reconstruction, every solver against refocusing -> results/reconstruct.{csv,md,json,png}
	$(VENV)/bin/python experiments/reconstruct.py --out $(TRADEOFF_OUT) $(RECON_ARGS_$(PRESET))
	if [ -f $(TRADEOFF_OUT)/tradeoff.csv ]; then \
		$(VENV)/bin/python experiments/tradeoff.py --reconstruction-only --out $(TRADEOFF_OUT); fi

# the learned reconstructor: training data by the exact operator (cached in data/learned), the network
# (models/reconstructor/paper, about 35 min on 2 cores), scored on traced renders beside admm (renders
# cached in data/fourier_solver). CAMERA=cam.toml trains for that camera -> models/reconstructor/cam,
# results/learned_cam/ (lf-flame reconstruct --solver learned --model models/reconstructor/cam)
train-reconstructor: $(STAMP) ## train the learned reconstructor of each plane's emission and score it -> models/reconstructor/paper, results/learned.{csv,md,json}, its rows in results/tradeoff.md
	$(VENV)/bin/python experiments/learned.py $(if $(CAMERA),--camera $(CAMERA) $(if $(CALIBRATION),--calibration $(CALIBRATION)) --models models/reconstructor/$(basename $(notdir $(CAMERA))) --out results/learned_$(basename $(notdir $(CAMERA))),--out $(TRADEOFF_OUT) $(if $(filter quick,$(PRESET)),--quick --models models/reconstructor/quick,))
	if [ -z "$(CAMERA)" ] && [ -f $(TRADEOFF_OUT)/tradeoff.csv ]; then \
		$(VENV)/bin/python experiments/tradeoff.py --reconstruction-only --out $(TRADEOFF_OUT); fi

# the camera's depth-resolution map (lf_flame.tomo.resolution; about 1.5 min on 2 cores)
resolution: $(STAMP) ## smallest resolvable plane spacing against feature size -> results/depth_resolution.{csv,md,png}
	$(VENV)/bin/python experiments/depth_resolution.py --out $(TRADEOFF_OUT)

cameras: $(STAMP) ## five cameras end to end from the CLI (white image, calibrate, decode, found depths, emission) and colour cameras' temperature (square and hexagonal grids) -> results/cameras{,_colour,_colour_hex}.{csv,md,json}, cameras.png
	$(VENV)/bin/python experiments/cameras.py --out $(TRADEOFF_OUT) $(if $(filter quick,$(PRESET)),--quick,)
	$(VENV)/bin/python experiments/cameras_colour.py --out $(TRADEOFF_OUT) $(if $(filter quick,$(PRESET)),--quick,)
	$(VENV)/bin/python experiments/cameras_colour.py --out $(TRADEOFF_OUT) --grid hex $(if $(filter quick,$(PRESET)),--quick,)

# admm's solve with OpenMP threads waiting passively (the package's setting) or spinning, on the light fields
# make cameras decoded (about 3 min on 2 cores)
floor: $(STAMP) ## each emission route's time as a multiple of this machine's floor (the views read once, one batched FFT pair), and where admm's time goes -> results/floor.{csv,md,json}
	$(VENV)/bin/python experiments/floor.py --out $(TRADEOFF_OUT)

one-command: $(STAMP) ## a 99 x 98-lenslet capture from its raw file to found depths and planes in one command (lf-flame reconstruct), timed as a whole process, where its time goes, and a recording of it decoded frame by frame -> results/one_command.{csv,md,json}
	$(VENV)/bin/python experiments/one_command.py --out $(TRADEOFF_OUT)

thread-wait: $(STAMP) ## (after make cameras) admm's solve time, OpenMP threads waiting passively against spinning -> results/thread_wait.{csv,md,json}
	$(VENV)/bin/python experiments/thread_wait.py --out $(TRADEOFF_OUT)

# find the planes: flames at random depths, found and reconstructed, beside the baselines (about 50 min
# on 2 cores for 100 scenes; each scene's rows cached in data/depth, so a rerun resumes)
depth: $(STAMP) ## flames at unknown depths (apart, one behind another, near focus): depth, emission and share errors per flame -> results/depth{,_columns,_bias}.{csv,md}, depth.png
	$(VENV)/bin/python experiments/depth.py --out $(TRADEOFF_OUT) $(DEPTH_ARGS_$(PRESET))
	$(VENV)/bin/python experiments/depth.py --out $(TRADEOFF_OUT) --bias $(if $(filter quick,$(PRESET)),6,60) --rays 100
	$(VENV)/bin/python experiments/depth.py --out $(TRADEOFF_OUT) --columns $(if $(filter quick,$(PRESET)),4,40) $(DEPTH_ARGS_$(PRESET))
	if [ -f $(TRADEOFF_OUT)/tradeoff.csv ]; then \
		$(VENV)/bin/python experiments/tradeoff.py --reconstruction-only --out $(TRADEOFF_OUT); fi

# axisymmetric volumetric flames: the axisymmetric prior beside the dense admm stack and
# shift-and-sum, noise-free and at 14 dB (about 15-20 min on 2 cores; renders cached in data/volume)
volume: $(STAMP) ## axisymmetric volumes: 3-D, projection and depth-centroid errors -> results/volume.{csv,md,json,png}
	$(VENV)/bin/python experiments/volume.py --out $(TRADEOFF_OUT)

# non-axisymmetric volumetric flames (the bar: centroid mean <= 0.3 mm, <= 10 % outside the true depth
# range): admm without prior, + TV, + l1 (weights chosen on validation volumes), the axisymmetric prior and
# shift-and-sum (over 15 min on 2 cores from no cache, so its own target; renders cached in data/volume)
volume-nonaxi: $(STAMP) ## non-axisymmetric volumes: centroid and outside-range shares -> results/volume_nonaxi.{csv,md,json,png}
	$(VENV)/bin/python experiments/volume.py --set nonaxi --out $(TRADEOFF_OUT)

# axisymmetric flames cut by the field's edge (0-30 % of their light outside): the axisymmetric prior with the light
# from beyond the field modelled, the same on the field's grid alone, admm (about 30 min on 2 cores; renders cached
# in data/volume)
volume-edge: $(STAMP) ## axisymmetric flames cut by the field's edge: axis and 3-D errors -> results/volume_edge.{csv,md,json}
	$(VENV)/bin/python experiments/volume.py --set edge --out $(TRADEOFF_OUT)

# the axis search's trial length (SEARCH_INNER), chosen on the validation volumes of axi-lam and edge
volume-search: $(STAMP) ## the axis search's trial length on validation volumes -> results/volume_search.{csv,md,json}
	$(VENV)/bin/python experiments/volume.py --set search --out $(TRADEOFF_OUT)

# the stem is REGIME/table_SCENE
$(RES)/%.md: $(MODELS)/$$(*D)/$$(subst table_,,$$(*F))/train_info.json
	$(LF) evaluate --dataset $(DATA)/$(*D)/$(subst table_,,$(*F)).h5 --model-dir $(<D) --results $(RES)/$(*D) \
		--heldout $(HELDOUT_$(PRESET)) --heldout-seed $(HELDOUT_SEED)

$(RES)/tables.md: $(foreach r,$(REGIMES),$(foreach s,$(SCENES),$(RES)/$(r)/table_$(s).md))
	$(LF) tables --results $(RES) --data-dir $(DATA) --model-dir $(MODELS)

tables: $(RES)/tables.md ## Tables I and II, slopes and figures in results/$(PRESET)

test: $(STAMP) $(NLF)/.installed $(DOCS_STAMP) ## run the test suite (includes an end-to-end run of the quick pipeline and a real capture's decode) and build the docs (strict)
	$(VENV)/bin/python -m pytest -q --durations=10
	$(VENV)/bin/mkdocs build --strict --quiet

clean-quick: ## remove the quick preset's data, models and results
	rm -rf data/quick models/quick results/quick
