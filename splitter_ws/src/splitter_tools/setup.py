from setuptools import find_packages, setup

PACKAGE_NAME = "splitter_tools"

setup(
    name=PACKAGE_NAME,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    include_package_data=True,
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + PACKAGE_NAME]),
        ("share/" + PACKAGE_NAME, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="SPLITTER developers",
    maintainer_email="splitter-dev@example.com",
    description="SPLITTER benchmarks (splitter bench), transport floor and garbage harness.",
    license="Apache-2.0",
)
