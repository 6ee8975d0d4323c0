from glob import glob

from setuptools import find_packages, setup

package_name = "evoscen_sim"

setup(
    name=package_name,
    version="0.4.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ('share/evoscen_sim/maps', sorted(glob('maps/*.xodr'))),
        ('share/evoscen_sim/config', sorted(glob('config/*.yaml'))),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="evoscen developers",
    maintainer_email="dev@evoscen.org",
    description="evoscen simulation core: OpenDRIVE road, vehicle dynamics, low-level PID control, collision, re-entry and the world step.",
    license="Apache-2.0",
    entry_points={"console_scripts": ["sim_node = evoscen_sim.sim_node:main"]},
)
