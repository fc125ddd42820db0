# Front doors. Each target sets everything up from nothing first (make setup).
.PHONY: setup demo test bench clean
RUN := tools/run.sh

setup:
	@bash tools/setup.sh

demo: setup
	@$(RUN) python -m torque_estimator.demo --out out/demo

test: setup
	@$(RUN) python -m pytest

bench: setup
	@$(RUN) python bench/run_all.py

clean:
	rm -rf ros_ws/build ros_ws/install ros_ws/log out
