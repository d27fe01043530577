"""The spec checks under the name docs/CI.md gave them (`bench.pytest_plugin.expect`): they live in bench.result.expect,
where a run outside pytest (bench.api.run) reaches them too."""

from __future__ import annotations

from bench.result.expect import *  # noqa: F403 - this module is that one's other name
from bench.result.expect import __all__ as __all__
