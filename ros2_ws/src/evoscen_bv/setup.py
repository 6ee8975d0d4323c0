
import os
from glob import glob

from setuptools import find_packages, setup

package_name = "evoscen_bv"

setup(
    name=package_name,
    version="0.4.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["py.typed", "config/*.yaml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", ["evoscen_bv/config/training.yaml"]),
        ("share/" + package_name + "/policies", sorted(f for f in glob("policies/*") if os.path.isfile(f))),
        # the first shipped set (trained at 40k/20k steps under the safety_net rules), selectable as policy_dir: v0.1.0
        ("share/" + package_name + "/policies/v0.1.0", sorted(glob("policies/v0.1.0/*"))),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="evoscen developers",
    maintainer_email="dev@evoscen.org",
    description="evoscen background-vehicle driver models (level-0 traffic and learned social drivers trained with TD3).",
    license="Apache-2.0",
    entry_points={"console_scripts": ["bv_node = evoscen_bv.bv_node:main"]},
)
