from glob import glob

from setuptools import find_packages, setup

package_name = "worm_model"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["data/*.yaml", "data/tro2021/*.md", "data/tro2021/LICENSE",
                                 "data/tro2021/**/*.csv"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="worm-torque maintainers",
    maintainer_email="maintainers@worm-torque.invalid",
    description="Worm-gear model: internal forces (paper Eqs 21-23), modes, switching torque, efficiencies, "
                "coupled motor and gearbox dynamics; model_node publishes the internal forces of every rig sample; "
                "worm_calc (one operating point) and report (the paper's Figs 6-11 from a calibration) are its CLIs.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "model_node = worm_model.nodes.model_node:main",
            "worm_calc = worm_model.calc.worm_calc:main",
            "rig_from_datasheet = worm_model.calc.datasheet:main",
            "report = worm_model.figures.report:main",
            "residuals = worm_model.residuals.cli:main",
        ],
    },
)
