"""atlasgen: a BRDF-to-atlas authoring toolchain for fully deferred renderers."""

__version__ = "0.2.0"
__all__ = ["__version__"]
