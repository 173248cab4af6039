"""Localization in a saved map: Monte Carlo localization with a likelihood field."""
