"""cli tool."""
