# turbinefit: the two commands of the README, plus benchmarks and checks.
# Each target creates its own virtual environment (.venv) and installs what it needs.

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
DEMO   := demo
# the CPU build of PyTorch (training only); an unpinned torch pulls a multi-GB CUDA build
TORCH  := 2.13.0
MODEL_IMAGES ?= 24000
MODEL_WIDTHS ?= 32,48,96,192
MODEL_EPOCHS ?= 8

.PHONY: demo test bench bench-blender model lint typecheck check clean

$(STAMP): pyproject.toml setup.py src/turbinefit/_kernels.c
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet torch==$(TORCH)
	$(BIN)/pip install --quiet -e '.[dev,train,ros,coco]'
	touch $(STAMP)

## demo: render a 200-keyframe flight with photos, detect heat-maps with the shipped CNN,
##       fit it, replay it through the in-flight tracker, say what each photo shows of each
##       blade, plan the next flight at 10 m and write the interactive page of it all
##       (demo/view.html); results and plots in demo/
demo: $(STAMP)
	$(BIN)/turbinefit simulate $(DEMO)/flight --keyframes 200 --seed 1 --images --overwrite
	$(BIN)/turbinefit detect $(DEMO)/flight/images/40.000000.png $(DEMO)/flight/images/120.000000.png \
		--out $(DEMO)/detect --overwrite
	$(BIN)/turbinefit fit $(DEMO)/flight --from-images --out $(DEMO)/fit --overwrite
	$(BIN)/turbinefit track $(DEMO)/flight --from-images --out $(DEMO)/track --overwrite
	$(BIN)/turbinefit coverage $(DEMO)/fit --out $(DEMO)/coverage --overwrite
	$(BIN)/turbinefit plan $(DEMO)/fit --standoff 10 --out $(DEMO)/plan --overwrite
	$(BIN)/turbinefit view $(DEMO) --out $(DEMO)/view.html --overwrite
	@echo "photos: $(DEMO)/flight/images; detections: $(DEMO)/detect; fit results and plots: $(DEMO)/fit; in-flight tracking: $(DEMO)/track; coverage: $(DEMO)/coverage; next flight: $(DEMO)/plan; all of it in 3-D: $(DEMO)/view.html"

## test: run the test suite
test: $(STAMP)
	$(BIN)/python -m pytest

## bench: accuracy and speed figures: fits on GPS/IMU and on odometry flights, 20 MP photos
##        (writes benchmarks/results/*.json)
bench: $(STAMP)
	$(BIN)/python benchmarks/bench_fit.py
	$(BIN)/python benchmarks/bench_detect.py
	$(BIN)/python benchmarks/bench_track.py
	$(BIN)/python benchmarks/bench_odometry.py
	$(BIN)/python benchmarks/bench_large.py

## bench-blender: the CNN on the same held-out views rendered by Blender's Cycles path tracer
##                (another renderer: does the net see turbines or its renderer's artefacts?);
##                needs Blender (Debian: apt-get install blender), ~30 min on 2 cores
bench-blender: $(STAMP)
	$(BIN)/python benchmarks/bench_blender.py

## model: train a heat-map CNN of the shipped one's shape from scratch on today's renders
##        (320x240 photos, 160x120 heat-maps, data version 4: 30 % close-ups; several hours
##        on 2 cores; see src/turbinefit/models/README.md for how the shipped one was made)
model: $(STAMP)
	$(BIN)/turbinefit train --out models/heatmap_cnn --images $(MODEL_IMAGES) --epochs $(MODEL_EPOCHS) \
		--widths $(MODEL_WIDTHS)
	cp models/heatmap_cnn/model.onnx src/turbinefit/models/heatmap_cnn.onnx
	cp models/heatmap_cnn/weights.npz src/turbinefit/models/heatmap_cnn.npz
	cp models/heatmap_cnn/history.csv src/turbinefit/models/heatmap_cnn_history.csv

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks

typecheck: $(STAMP)
	$(BIN)/mypy

check: lint typecheck test

clean:
	rm -rf $(VENV) $(DEMO) .pytest_cache .mypy_cache .ruff_cache
