# Two entry points: `make bench` (the main job on the embedded defaults) and `make test`.
# Both create .venv/ when missing and install the project with torch pinned (constraints.txt).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: bench test perf install clean clean-cache

$(STAMP): pyproject.toml constraints.txt
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --upgrade pip
	$(BIN)/python -m pip install -c constraints.txt torch==2.13.0
	$(BIN)/python -m pip install -c constraints.txt -e ".[test]"
	touch $(STAMP)

install: $(STAMP)

# Every table under leaderboards/, in about 15 min on 2 idle cores, its last line the total wall
# time (each bench command also ends with its own wall time and the CPU time per env):
# - every benchmark env and compensator on 6 seeds (each its own drawn plant and fits; 6 is the
#   fewest whose 95 % median interval can mean 95 %: fricbench/bench/statistics.py); the
#   settings file trims tf-lstm-precomp's per-seed training (see its comments);
# - leaderboards/nominal/: the paper's nominal axis, one seed, one fit of each compensator with
#   its registered defaults (tf-lstm-precomp's full training), as docs/compensators.md cites.
# --fresh: each table holds that run's rows alone. More seeds: BENCH_SEEDS="0 1 2 3 4 5 6 7 8 9"
BENCH_SEEDS ?= 0 1 2 3 4 5
bench: $(STAMP)
	@start=$$(date +%s); status=0; \
	$(BIN)/fricbench bench --compensator-config leaderboards/bench.toml --seeds $(BENCH_SEEDS) \
		--fresh || status=$$?; \
	[ $$status -ne 0 ] || $(BIN)/fricbench bench --nominal --seeds 0 --fresh \
		--envs fricbench/PaperAxis-v0 fricbench/PaperAxisShifted-v0 || status=$$?; \
	echo "make bench: total wall time $$(( $$(date +%s) - start )) s"; exit $$status

test: $(STAMP)
	$(BIN)/ruff check fricbench tests examples
	$(BIN)/mypy fricbench
	$(BIN)/python -m pytest -n 2 -q tests

perf: $(STAMP)
	$(BIN)/fricbench perf --json out/perf.json

clean:
	rm -rf $(VENV)

# numba's on-disk cache does not see edits to functions inlined from another module (the kernel
# inlines the friction laws; the vector step inlines the kernel): clear it after such edits
clean-cache:
	find fricbench -name '*.nbi' -delete -o -name '*.nbc' -delete
