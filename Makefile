# xfem-cut: `make test` and `make report` install what they need on a fresh machine.
SHELL := /bin/bash
CARGO ?= $(shell command -v cargo || echo $$HOME/.cargo/bin/cargo)
NP ?= 1

.PHONY: all build test report bench rust refs-env refs refs-test clean

all: build

# Rust toolchain: present on these machines through rustup; fail clearly otherwise.
rust:
	@command -v $(CARGO) >/dev/null || { echo "error: cargo not found (install Rust with rustup)"; exit 1; }

build: rust
	$(CARGO) build --release

-include refs/refs.mk

# The tests: references at the levels the tests need, then every Rust test (release: the FE tests are heavy).
test: build $(if $(wildcard refs/refs.mk),refs-test)
	$(CARGO) test --release

bench: build
	$(CARGO) bench --bench step

report: build $(if $(wildcard refs/refs.mk),refs)
	@mkdir -p reports
	$(CARGO) run --release -- run cases/gravity_uncut.toml --out out/gravity_uncut

clean:
	rm -rf target out
