
from setuptools import find_packages, setup

package_name = "evoscen_eval"

setup(
    name=package_name,
    version="0.4.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="evoscen developers",
    maintainer_email="dev@evoscen.org",
    description="evoscen evaluation: metrics and reports.",
    license="Apache-2.0",
    entry_points={"console_scripts": ["eval_node = evoscen_eval.eval_node:main"]},
)
