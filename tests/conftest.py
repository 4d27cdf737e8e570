"""Suite-wide test ordering.

Browser tests run last: Playwright's sync API keeps an event loop running in the main thread
for as long as its (session-scoped) browser lives, and any later test that calls
``asyncio.run()`` would then fail with "cannot be called from a running event loop".
"""

from __future__ import annotations

import pytest


def pytest_collection_modifyitems(
    session: pytest.Session, config: pytest.Config, items: list[pytest.Item]
) -> None:
    items.sort(key=lambda item: item.get_closest_marker("browser") is not None)
