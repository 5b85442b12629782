"""Rendering of results: tables (CSV + Markdown), run metadata, charts, 3-D pictures, the one-screen
verdict and the HTML page; ``spq report`` (assemble.py: run the suites, then build index.html and
REPORT.md from what they wrote) and ``spq view`` (viewer.py: the interactive viewer in the browser)."""
