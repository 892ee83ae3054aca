"""Pictures of a run: the summary figure, the 3-D animation and the browser viewer
(with its headless Chromium driver).

This folder owns drawing results. It must not simulate.
"""
