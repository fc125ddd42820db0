# Front doors. Each target sets everything up from nothing first (make setup).
# ROS_DISTRO=kilted (default) or jazzy: which ROS 2 wheels to build and run against (tools/distro.sh);
# each has its own lock file, venv and colcon folders. TESTS: pytest arguments (default: every test).
.PHONY: setup demo evaluate test bench clean
RUN := tools/run.sh
ROS_DISTRO ?= kilted
export ROS_DISTRO
TESTS ?=

setup:
	@bash tools/setup.sh

demo: setup
	@$(RUN) python -m torque_estimator.experiment.demo --out out/demo

evaluate: setup
	@$(RUN) python -m torque_estimator.experiment.evaluate --out out/evaluate

test: setup
	@$(RUN) python -m pytest $(TESTS)

bench: setup
	@$(RUN) python bench/run_all.py

# The rig firmware in the loop (simavr) with driver_node connected; ends with one `fil: ...` line.
FIRMWARE := ros_ws/src/worm_rig_driver/firmware
fil: setup
	@$(MAKE) -s -C $(FIRMWARE) all fil
	@$(RUN) python -m worm_rig_driver.fil.run --elf $(FIRMWARE)/build/rig.elf --harness $(FIRMWARE)/build/libwormfil.so

clean:
	rm -rf ros_ws/build ros_ws/install ros_ws/log ros_ws/build-jazzy ros_ws/install-jazzy ros_ws/log-jazzy out
