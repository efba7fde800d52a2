# xfem-cut: `make test` and `make report` install what they need on a fresh machine.
SHELL := /bin/bash
CARGO ?= $(shell command -v cargo || echo $$HOME/.cargo/bin/cargo)
NP ?= 1
# Untimed work at once on this machine's two cores: meshes, graded and corotational references,
# the corotational study's halves, the exact study, the stress suite, pictures. What the report
# sets times of (FEniCSx's level solves, the linear study, the sweep, the benches) runs alone.
JOBS ?= 2

.PHONY: all build test fuzz report bench bench-report bench-static rust refs-env refs refs-test clean

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

# Fuzzing on stable Rust: 10^6 mutated case files and meshes through parse, validate and set-up
# (`make test` runs the same test with 10^5).
FUZZ_COUNT ?= 1000000
fuzz: rust
	XFEM_FUZZ_COUNT=$(FUZZ_COUNT) $(CARGO) test --release --test fuzz -- --nocapture

bench: build
	$(CARGO) bench --bench step --bench cut --bench blade

REPORT_CASES := gravity stretch bend stretch_face bend_face slice
CONVERGE_CSV := reports/data/convergence.csv
# The corotational study: the seed's gravity beam, the large-deformation face cases, the through cut.
COROT_CASES := gravity stretch_face bend_face slice
CONVERGE_COROT_CSV := reports/data/convergence_corot.csv
STRESS_CSV := reports/data/stress.csv
# Code verification (exact solutions, no references needed): re-run when the binary changed;
# `converge --exact` itself skips a run whose inputs hash (binary + variants) is unchanged.
EXACT_CSV := reports/data/exact.csv
# A blade sweeping the seed's cut: step time against simulated time, events marked; the front
# extended and tip-enriched, linear and corotational (seconds).
SWEEP_CSV := reports/data/sweep_series.csv
# What the ramp of corrected X-FEM buys on the beam against R / h (`cut::RAMP_SPAN`): 240 static
# Tet4 solves against the references (about 10 minutes).
RAMP_CASES := gravity stretch_face bend_face stretch
RAMP_CSV := reports/data/ramp_span.csv
# The tip front beside remeshed FEM on one mesh per level, uniform and graded at the face cases'
# strip edges, and the tip front on the uncut body graded alike (`examples/error_map.rs one-mesh`,
# 70 static solves, about 3.5 minutes; Tet4 to L4, Tet10 to L3).
ONE_MESH_CASES := bend_face stretch_face
ONE_MESH_CSV := reports/data/one_mesh.csv

# The main job: references, the convergence studies, the benches, the report. Untimed stages run
# $(JOBS) at a time; the timed ones (the linear study, the sweep, the benches) alone after them.
report: build
	$(if $(wildcard refs/refs.mk),$(MAKE) refs)
	$(MAKE) -j$(JOBS) $(CONVERGE_COROT_CSV) $(EXACT_CSV) $(STRESS_CSV) $(RAMP_CSV) $(ONE_MESH_CSV)
	$(MAKE) $(CONVERGE_CSV) $(SWEEP_CSV) bench-report
	$(if $(wildcard refs/refs.mk),$(MAKE) -j$(JOBS) pictures)
	$(CARGO) run --release -- report

# Re-run the study when the solver, a case or a reference changed.
$(CONVERGE_CSV): target/release/xfem-cut $(foreach c,$(REPORT_CASES),cases/$(c).toml refs/out/$(c)/manifest.json)
	$(CARGO) run --release -- converge $(foreach c,$(REPORT_CASES),cases/$(c).toml) --csv $@ --max-dofs 120000

# Every variant corotational, against our corotational Tet10 FEM on the finest pre-cut level ≤ 120k DOFs:
# in two halves that can run at once (out/study/corot_*.csv), joined in case order.
COROT_HALF_a := gravity stretch_face
COROT_HALF_b := bend_face slice
$(CONVERGE_COROT_CSV): out/study/corot_a.csv out/study/corot_b.csv
	@mkdir -p $(dir $@)
	{ cat out/study/corot_a.csv; tail -n +2 out/study/corot_b.csv; } > $@.tmp && mv $@.tmp $@

out/study/corot_%.csv: target/release/xfem-cut $(foreach c,$(COROT_CASES),cases/$(c).toml refs/out/$(c)/manifest.json)
	@mkdir -p $(dir $@)
	rm -f $@.tmp
	$(CARGO) run --release -- converge --corotational $(foreach c,$(COROT_HALF_$*),cases/$(c).toml) --csv $@.tmp --max-dofs 120000
	mv $@.tmp $@

# The exact-solution study (a few minutes on 2 cores), with progress per solve.
$(EXACT_CSV): target/release/xfem-cut
	$(CARGO) run --release -- converge --exact --csv $@

# The stress suite: re-run when the solver changed.
$(STRESS_CSV): target/release/xfem-cut
	@mkdir -p $(dir $@)
	$(CARGO) run --release -- stress --csv $@ || echo "stress: a test failed; the report shows which"

$(SWEEP_CSV): target/release/xfem-cut examples/sweep_series.rs
	$(CARGO) run --release --example sweep_series -- --out reports
	$(CARGO) run --release --example sweep_series -- corotational --out reports
	$(CARGO) run --release --example sweep_series -- tip --out reports
	$(CARGO) run --release --example sweep_series -- corotational tip --out reports

$(RAMP_CSV): target/release/xfem-cut examples/error_map.rs $(foreach c,$(RAMP_CASES),cases/$(c).toml refs/out/$(c)/manifest.json)
	$(CARGO) run --release --example error_map -- ramp-span --csv $@

$(ONE_MESH_CSV): target/release/xfem-cut examples/error_map.rs $(ONE_MESH_MESHES) $(foreach c,$(ONE_MESH_CASES),cases/$(c).toml refs/out/$(c)/manifest.json)
	$(CARGO) run --release --example error_map -- one-mesh --csv $@

bench-report: build
	$(CARGO) bench --bench step --bench cut --bench blade -- --warm-up-time 1 --measurement-time 3

# Static solves against FEniCSx at equal cores, 13k–376k DOFs (tens of minutes, and it wants a
# quiet machine): the report's "Static solve against FEniCSx" section, run apart from `make report`.
bench-static: build refs-env
	cd refs && $(REFS_PY) bench_static.py

clean:
	rm -rf target out
