from glob import glob

from setuptools import find_packages, setup

package_name = "torque_estimator"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: []},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="worm-torque maintainers",
    maintainer_email="maintainers@worm-torque.invalid",
    description="Sensorless load-torque estimation for worm gearboxes: calibration, k-NN estimator node, "
                "and a velocity controller node with torque feedforward.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "estimator_node = torque_estimator.nodes.estimator_node:main",
            "controller_node = torque_estimator.nodes.controller_node:main",
            "calibrate = torque_estimator.calibration.calibrate:main",
            "evaluate = torque_estimator.evaluation.evaluate:main",
            "run_graph = torque_estimator.graph.run_graph:main",
            "demo = torque_estimator.demo.demo:main",
            "replay = torque_estimator.offline.replay:main",
            "identify = torque_estimator.identification.identify:main",
            "estimate = torque_estimator.offline.estimate:main",
            "health_check = torque_estimator.health.health_check:main",
            "health_monitor = torque_estimator.health.monitor_node:main",
        ],
        # the estimator sim_node / driver_node run beside their speed loop (worm_rig_driver.drive.feedforward_plugin)
        "worm_rig_driver.feedforward": [
            "torque_estimator = torque_estimator.control.rig_feedforward:build",
        ],
    },
)
