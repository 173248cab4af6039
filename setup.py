"""Package discovery for the package-dir mapping in pyproject.toml.

`frontends/` and `backends/` live at the top of the repository but install as
`smokyslam.frontends` and `smokyslam.backends`; setuptools' automatic discovery
would install them as top-level modules, so the list is built here.
"""

from setuptools import find_packages, setup


def _mapped(package: str, folder: str) -> list[str]:
    return [package] + [f"{package}.{sub}" for sub in find_packages(folder)]


setup(
    packages=find_packages(include=["smokyslam", "smokyslam.*"])
    + _mapped("smokyslam.frontends", "frontends")
    + _mapped("smokyslam.backends", "backends")
)
