# goniospec: the commands README.md promises. Each installs Debian's Embree, libclang
# and pkg-config first when they are missing.

CARGO ?= cargo

.PHONY: demo test deps bench lint

OUT ?= out/demo

## Run the main job on the built-in default sample: simulate the seed's 600 nm wavy soap
## film, and print its reflectance next to the flat film's analytic reference.
demo: deps
	$(CARGO) build --release
	mkdir -p $(OUT)
	./target/release/goniospec backends
	./target/release/goniospec check meshes/thin-film-600nm.toml --leak-rays 5000
	./target/release/goniospec simulate meshes/thin-film-600nm.toml --theta-i 0,30,60 --rays 8192 -o $(OUT)/thin-film-600nm.gsa
	./target/release/goniospec reflectance $(OUT)/thin-film-600nm.gsa --theta-i 30 > $(OUT)/reflectance-30deg.csv
	./target/release/goniospec analytic meshes/flat-soap-film.toml --theta-i 30 > $(OUT)/flat-film-tmm-30deg.csv
	@echo "reflectance at 30 deg (wavy film, simulated) against the flat 600 nm film (TMM):"
	@paste -d, $(OUT)/reflectance-30deg.csv $(OUT)/flat-film-tmm-30deg.csv | cut -d, -f1,2,6,10 | awk -F, 'NR == 1 { print "lambda_nm  R_wavy       R_wavy_stderr  R_flat_TMM"; next } { printf "%-10s %-12s %-14s %s\n", $$1, $$2, $$3, $$4 }'
	@echo "wrote $(OUT)/thin-film-600nm.gsa, $(OUT)/reflectance-30deg.csv and $(OUT)/flat-film-tmm-30deg.csv"

## Benchmarks: raw intersector throughput, and end-to-end simulation speed.
bench: deps
	$(CARGO) run --release -- bench trace
	$(CARGO) run --release -- bench simulate
	$(CARGO) run --release -- bench eval

## Run the whole test suite.
test: deps
	$(CARGO) test --all-targets

## Formatting and lints, as CI applies them.
lint: deps
	$(CARGO) fmt --all -- --check
	$(CARGO) clippy --all-targets -- -D warnings

## Install system packages when missing.
deps:
	@./scripts/install-deps.sh
