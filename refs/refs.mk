# The reference pipeline (included by the top-level Makefile).
REFS_PY := /usr/bin/python3
REFS_DEBS := python3-dolfinx python3-gmsh python3-meshio python3-scipy python3-matplotlib libopenblas0-pthread python3-venv openmpi-bin

.PHONY: refs-env refs refs-test refs-uniform pictures oblique hole

# Debian's FEniCSx, gmsh and meshio (with OpenBLAS for a fair MUMPS), installed when missing.
refs-env:
	@if ! $(REFS_PY) -c "import dolfinx, gmsh, meshio, scipy, matplotlib" 2>/dev/null || ! dpkg -s libopenblas0-pthread >/dev/null 2>&1; then \
	  echo "refs: installing $(REFS_DEBS)"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(REFS_DEBS) >/dev/null; \
	fi
	@$(REFS_PY) -c "import dolfinx, gmsh, meshio; print('refs: dolfinx', dolfinx.__version__)"
	@# scikit-fem from PyPI in a venv that sees Debian's numpy, scipy and meshio.
	@if ! refs/.venv/bin/python -c "import skfem" 2>/dev/null; then \
	  echo "refs: creating refs/.venv with scikit-fem"; \
	  rm -rf refs/.venv && $(REFS_PY) -m venv --system-site-packages refs/.venv && refs/.venv/bin/pip install -q scikit-fem; \
	fi

# Every level and the fine reference (make refs NP=4 runs the solves under mpirun).
refs: refs-env
	cd refs && $(REFS_PY) make_refs.py --set all --np $(NP) --jobs $(JOBS)

# The coarse levels the tests need.
refs-test: refs-env
	cd refs && $(REFS_PY) make_refs.py --set test --np $(NP) --jobs $(JOBS)

# The old reference (uniform 2.8 mm, P2, CG + GAMG): only to measure its error against the graded one.
refs-uniform: refs-env
	cd refs && $(REFS_PY) make_refs.py --set uniform --np $(NP)

# Random oblique crack fronts (edge, corner and inside patches) against remeshed references:
# X-FEM tip / geometric tip / extend and pre-cut FEM, Tet4 and Tet10, per level
# (refs/oblique/run.py; about 45 min for the 8 default scenes on 2 cores; not part of
# `make report`): refs/out/oblique/summary.txt. `make oblique SEEDS="11 14"` runs those scenes.
oblique: build refs-env
	cd refs/oblique && $(REFS_PY) run.py $(SEEDS)

# A slit towards a vessel (a block around a hole, the front 5 mm from its wall) against a
# remeshed reference graded at the front and an ungraded one: X-FEM tip / geometric tip /
# extend and pre-cut FEM, Tet4 and Tet10, per level (refs/hole/run.py; about 3 min on 2
# cores; not part of `make report`): refs/out/hole/summary.txt.
hole: build refs-env
	cd refs/hole && $(REFS_PY) run.py

# Pictures (headless): X-FEM structured level 2 Tet4 with its cut opened beside the graded
# reference, reports/pictures/<case>.png; remade when the solver, the case or the reference changed.
PICTURE_CASES := gravity stretch bend stretch_face bend_face slice
pictures: $(foreach c,$(PICTURE_CASES),reports/pictures/$(c).png) reports/pictures/cut_progressive_sweep.png

# The blade of `cut_progressive` as it cuts: five frames of its level-1 `.pvd` series.
reports/pictures/cut_progressive_sweep.png: target/release/xfem-cut cases/cut_progressive.toml refs/sweep_pictures.py refs/pictures.py
	target/release/xfem-cut run cases/cut_progressive.toml --level 1 --out out/pictures/cut_progressive >/dev/null
	cd refs && $(REFS_PY) sweep_pictures.py cut_progressive ../out/pictures/cut_progressive/result.pvd ../$@

reports/pictures/%.png: target/release/xfem-cut cases/%.toml refs/pictures.py refs/own_error.py refs/out/%/manifest.json
	target/release/xfem-cut run cases/$*.toml --level 2 --out out/pictures/$* >/dev/null
	cd refs && $(REFS_PY) pictures.py $* ../out/pictures/$*/result.vtu \
	  out/$*/$(if $(filter slice,$*),slice_precut,beam_crack)_fine/p2.vtu ../$@ \
	  --title "$*: X-FEM structured level 2, Tet4 (left) and the graded FEniCSx P2 reference (right), deformed at true scale"

# The one-mesh comparison's meshes (`examples/error_map.rs one-mesh`): gmsh's crack mesh of levels
# L1-L4 (Tet10 runs L1-L3) with the crack's nodes shared, uniform as the level (beam_crack_shared) and graded to h/4
# at the top-face strips' free edges (beam_crack_shared_strips), and the body without the crack
# graded alike (beam_uncut_strips: X-FEM's front inside elements, as in the study). h per level as
# make_refs.py's LEVELS.
LEVEL_H = $(word $(shell echo $$(($(1) + 1))),0.012 0.008 0.006 0.0045 0.0035)
ONE_MESH_MESHES := $(foreach l,1 2 3 4,$(foreach f,beam_crack_shared beam_crack_shared_strips beam_uncut_strips,refs/out/meshes/$(f)/L$(l).msh))

refs/out/meshes/beam_crack_shared/L%.msh: refs/crack_mesh_uncut.py refs/mesh.py
	cd refs && $(REFS_PY) crack_mesh_uncut.py $(call LEVEL_H,$*) out/meshes/beam_crack_shared/L$*.msh

refs/out/meshes/beam_crack_shared_strips/L%.msh: refs/crack_mesh_uncut.py refs/mesh.py
	cd refs && $(REFS_PY) crack_mesh_uncut.py $(call LEVEL_H,$*) out/meshes/beam_crack_shared_strips/L$*.msh \
	  --strip-edges $(shell awk 'BEGIN { print $(call LEVEL_H,$*) / 4 }')

refs/out/meshes/beam_uncut_strips/L%.msh: refs/crack_mesh_uncut.py refs/mesh.py
	cd refs && $(REFS_PY) crack_mesh_uncut.py $(call LEVEL_H,$*) out/meshes/beam_uncut_strips/L$*.msh \
	  --strip-edges $(shell awk 'BEGIN { print $(call LEVEL_H,$*) / 4 }') --uncut
