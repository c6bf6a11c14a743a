"""Compatibility alias: the ``aidnav tight`` job lives in :mod:`aidnav.apps.tight`."""

from aidnav.apps.tight import *  # noqa: F403
from aidnav.apps.tight import compare_with_reference, process_tight, process_tight_files  # noqa: F401
