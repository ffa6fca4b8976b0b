# goniospec: the commands README.md promises. Each installs Debian's Embree, libclang
# and pkg-config first when they are missing.

CARGO ?= cargo

.PHONY: demo test deps bench lint

## Run the main job on the built-in default sample (for now: the trace benchmark).
demo: deps
	$(CARGO) run --release -- backends
	$(CARGO) run --release -- check meshes/thin-film-600nm.toml
	$(CARGO) run --release -- bench trace

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
