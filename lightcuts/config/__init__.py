"""YAML run configs: schema, loading, ``--set`` overrides."""

from lightcuts.config.schema import RunConfig, load_config

__all__ = ["RunConfig", "load_config"]
