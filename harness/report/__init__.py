"""Rendering of results: tables (CSV + Markdown) and run metadata."""
