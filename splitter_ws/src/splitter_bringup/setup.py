from glob import glob

from setuptools import find_packages, setup

PACKAGE_NAME = "splitter_bringup"

setup(
    name=PACKAGE_NAME,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={"": ["*.xml", "*.yaml", "*.json"], PACKAGE_NAME: ["scenarios/*.yaml"]},
    include_package_data=True,
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + PACKAGE_NAME]),
        ("share/" + PACKAGE_NAME, ["package.xml"]),
        ("share/" + PACKAGE_NAME + "/config", glob("config/*.yaml")),
        ("share/" + PACKAGE_NAME + "/launch", glob("launch/*.launch.py")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="SPLITTER developers",
    maintainer_email="splitter-dev@example.com",
    description="SPLITTER scenarios, run backends, analysis, figures, tool nodes and CLI.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "splitter = splitter_bringup.cli.main:main",
        ],
    },
)
