from glob import glob

from setuptools import find_packages, setup

package_name = "worm_rig_driver"

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
    description="The worm-gear rig: sim_node (simulated rig) publishing currents, velocities, encoder counts "
                "and synchronized samples, and the bag recorder.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "sim_node = worm_rig_driver.nodes.sim_node:main",
            "recorder = worm_rig_driver.nodes.recorder_node:main",
            "bag = worm_rig_driver.recording.bag_cli:main",
            "worm_effects = worm_rig_driver.sim.effects.cli:main",
            "virtual_rig = worm_rig_driver.sim.virtual_rig:main",
            "driver_node = worm_rig_driver.nodes.driver_node:main",
            "joint_state_merger = worm_rig_driver.nodes.joint_state_merger:main",
        ],
    },
)
