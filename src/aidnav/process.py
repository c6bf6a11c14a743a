"""Compatibility alias: the ``aidnav process`` job lives in :mod:`aidnav.apps.process`."""

from aidnav.apps.process import *  # noqa: F403
from aidnav.apps.process import ConfigError, load_config, process, process_logs  # noqa: F401
