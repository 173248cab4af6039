"""Runs that wire stages together: each reads like a table of contents and returns a result."""
