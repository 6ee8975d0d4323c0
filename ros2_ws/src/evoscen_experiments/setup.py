"""The package's metadata and files are declared in setup.cfg."""

from setuptools import setup

setup()
