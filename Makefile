# goniospec: the commands README.md promises. Each installs Debian's Embree, libclang
# and pkg-config first when they are missing.

CARGO ?= cargo

.PHONY: demo test deps bench lint study stress fuzz fuzz-smoke fuzz-replay interop python report

OUT ?= out/demo

# The release binary, wherever cargo puts it (CARGO_TARGET_DIR is honoured).
BIN = $(or $(CARGO_TARGET_DIR),target)/release/goniospec

## Run the main job on the built-in default sample: simulate the seed's 600 nm wavy soap
## film, build its BRDF, render a sphere made of it (EXR + PNG), and write a short summary.
demo: deps
	$(CARGO) build --release
	GONIOSPEC=$(BIN) ./scripts/demo.sh $(OUT)

## Benchmarks: raw intersector throughput, and end-to-end simulation speed.
bench: deps
	$(CARGO) run --release -- bench trace
	$(CARGO) run --release -- bench simulate
	$(CARGO) run --release -- bench eval
	$(CARGO) run --release -- bench large

## Run the whole test suite, then the batch test on a local Slurm cluster (as root; it
## says so when it cannot run).
# In the release profile: the build the demo, interop, Python and benchmarks use, so CI
# builds goniospec once (issue 75: the debug build and then the release one took 285 s and
# 242 s of a fresh clone's 2,235 s; the suite in release, built and run, 330 s and 272 s).
# The tests that need debug assertions and overflow checks, on hostile input (the CLI,
# sample loading, the acceleration handles), run in the debug build without Embree
# (`.ci/run`), and the fuzz replay checks every parser in debug (`make fuzz-smoke`).
test: deps
	$(CARGO) test --release --all-targets
	./scripts/slurm-test.sh $(BIN)

## The house gate (scripts/house-figures.py --check: function and file lengths, import
## cycles, the floors of docs/design.md §9, string errors; limits in
## scripts/house-limits.toml), then formatting and lints, as CI applies them: the Embree
## build and the build without it.
# The Embree-less build has its own target folder, so that switching between the two does
# not rebuild goniospec each time; CI, which builds each once, shares the dependencies.
NO_EMBREE_TARGET ?= $(or $(CARGO_TARGET_DIR),target)/no-embree
lint: deps
	python3 scripts/house-figures.py --check
	$(CARGO) fmt --all -- --check
	$(CARGO) clippy --all-targets -- -D warnings
	GONIOSPEC_NO_EMBREE=1 CARGO_TARGET_DIR=$(NO_EMBREE_TARGET) $(CARGO) clippy --all-targets -- -D warnings

## Install system packages when missing.
deps:
	@./scripts/install-deps.sh

## A small default study (a few seconds): CSV, report and charts in out/study.
study: deps
	$(CARGO) build --release
	$(BIN) study studies/flat-film.toml -o out/study/flat-film
	$(BIN) study studies/rough-glass.toml -o out/study/rough-glass
	$(BIN) study studies/darkening.toml -o out/study/darkening
	$(BIN) study studies/grating-methods.toml -o out/study/grating-methods

## The stress studies (about 30 s): where each method breaks. Reports in out/stress/*/;
## docs/stability.md summarises them.
STRESS = grazing thick-film thin-film seed-experiment radius-flat radius-curved radius-wedge buckets v-groove precision
stress: deps
	$(CARGO) build --release
	for s in $(STRESS); do $(BIN) study studies/$$s.toml -o out/stress/$$s || exit 1; done

## Fuzz every parser (OBJ, sample TOML, media tables and models, .gsa, .gsb, studies, CLI
## values) with AFL++ through afl.rs on stable Rust, FUZZ_SECONDS each (default 600).
## Installs cargo-afl when missing. Findings in out/fuzz/; see fuzz/README.md.
FUZZ_SECONDS ?= 600
fuzz: deps
	./scripts/fuzz.sh $(FUZZ_SECONDS)

## What CI runs: the harnesses build (without AFL) and replay every corpus and regression
## input, goniospec's code with debug assertions and overflow checks (about 75 s).
fuzz-replay: deps
	cd fuzz && $(CARGO) test

## The replay, then each target fuzzed under AFL for a few seconds (about a minute in
## all). The instrumented build takes about 4 minutes on 2 cores whatever its opt-level
## or codegen units (measured: afl.rs rebuilds every dependency with its own flags).
fuzz-smoke: fuzz-replay
	./scripts/fuzz.sh 3

## Interop: export RGL .bsdf files (rough gold, the seed's wavy film) and check them with an
## independent reader and with Mitsuba 3 (installed into .venv-interop from PyPI).
interop: deps
	$(CARGO) build --release
	./scripts/interop.sh $(BIN)

## The Python package (python/: pyo3 + maturin): build the self-contained wheel (Embree and
## TBB inside), install it into .venv-python with numpy, pytest and tmm, run its tests
## against the CLI, then install it where the system's Embree and TBB are hidden.
python: deps
	$(CARGO) build --release
	./scripts/python.sh $(BIN)
	./scripts/wheel-isolated.sh

## The batch report in a real browser: a three-material library, its page opened by headless
## Chromium (Selenium, chromium-driver; installed when missing), strict HTML5 parse, colours
## against colour-science; screenshot in out/report-browser/report.png.
report: deps
	$(CARGO) build --release
	./scripts/report-browser.sh $(BIN)
