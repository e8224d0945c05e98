# The front door. `make demo` and `make test` install what is missing first.
SHELL := /bin/bash
CARGO ?= cargo

.PHONY: deps demo test lint bench clean-deps

deps:
	@bash tools/setup.sh

demo: deps
	$(CARGO) build --release --bin omcl
	./target/release/omcl demo --out demo-out

lint: deps
	$(CARGO) fmt --all -- --check
	$(CARGO) clippy --all-targets -- -D warnings
	python3 tools/check_cycles.py src
	RUSTDOCFLAGS="-D warnings" $(CARGO) doc --no-deps --quiet

test: deps lint
	$(CARGO) test --lib --bins --tests

bench: deps
	$(CARGO) bench
