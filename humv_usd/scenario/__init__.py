"""Scenario files: the user's description of who, what, where, when and seen by which sensor."""

from humv_usd.scenario.load import Scenario, load_scenario, validate

__all__ = ["Scenario", "load_scenario", "validate"]
