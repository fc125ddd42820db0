# Front doors. Each target sets everything up from nothing first (make setup).
# ROS_DISTRO=kilted (default) or jazzy: which ROS 2 wheels to build and run against (tools/distro.sh);
# each has its own lock file, venv and colcon folders. TESTS: pytest arguments (default: every test).
.PHONY: setup demo evaluate test test-system bench soak clean
RUN := tools/run.sh
ROS_DISTRO ?= kilted
export ROS_DISTRO
TESTS ?=
# Test files run two at a time (pytest-xdist, a file's tests together in one worker; each worker's DDS domains
# are its own, worm_model.ros.testing.local_domain): most system tests wait on the rig's real time, not on a
# core. JOBS=1 runs them one after another.
JOBS ?= 2
PARALLEL := $(if $(filter 1,$(JOBS)),,-n $(JOBS) --dist loadfile)

setup:
	@bash tools/setup.sh

demo: setup
	@mkdir -p out
	@$(RUN) python -m torque_estimator.demo.demo --out out/demo --force

evaluate: setup
	@mkdir -p out
	@$(RUN) python -m torque_estimator.evaluation.evaluate --out out/evaluate --force

test: setup
	@$(RUN) python -m pytest $(PARALLEL) $(TESTS)

# The system tests: what can differ from one ROS 2 distribution to the next. Nodes as processes over DDS, the
# driver over a pty, the firmware in simavr, the demo, the README's commands, the bags and Foxglove decoding them,
# every executable's refusal of bad options and parameters. Left out: the tests that never touch ROS (residual
# analysis on the simulator, the foreign plant, the README's computed figures, static import/dependency checks,
# ruff), and those that drive the same nodes and executables as the ones above through our offline tools and
# benchmarks (the new-drive page, the tools' file round trip, the soak benchmark). CI's run on the second
# distribution (.ci/run: make test-system ROS_DISTRO=jazzy).
NOT_SYSTEM := tests/test_residuals_cases.py tests/test_residuals_sim.py tests/test_readme_figures.py tests/test_docs.py \
              tests/test_layout.py tests/test_package_deps.py tests/test_lint.py tests/test_bench_scripts.py \
              tests/test_foreign_plant.py tests/test_effect_vocabulary.py \
              tests/test_new_drive.py tests/test_tool_round_trip.py tests/test_soak_bench.py
SYSTEM_TESTS := $(filter-out $(NOT_SYSTEM),$(sort $(wildcard tests/test_*.py)))
test-system: setup
	@$(RUN) python -m pytest $(PARALLEL) $(SYSTEM_TESTS) $(TESTS)

bench: setup
	@$(RUN) python bench/run_all.py

# The soak (not part of bench: an hour): the shipped graph and the recorder for MINUTES under a seeded command
# profile, figures per 10-minute window and a verdict per target (bench/soak_bench.py --help). SOAK_ARGS: more
# options, e.g. "--chaos --seed 3" (faults injected) or "--window 60".
MINUTES ?= 60
SOAK_ARGS ?=
soak: setup
	@$(RUN) python bench/soak_bench.py --minutes $(MINUTES) $(SOAK_ARGS)

# The rig firmware in the loop (simavr) with driver_node connected; ends with one `fil: ...` line.
FIRMWARE := ros_ws/src/worm_rig_driver/firmware
fil: setup
	@$(MAKE) -s -C $(FIRMWARE) all fil
	@$(RUN) python -m worm_rig_driver.fil.run --elf $(FIRMWARE)/build/rig.elf --harness $(FIRMWARE)/build/libwormfil.so

clean:
	rm -rf ros_ws/build ros_ws/install ros_ws/log ros_ws/build-jazzy ros_ws/install-jazzy ros_ws/log-jazzy out
