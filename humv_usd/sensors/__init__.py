"""sensors tool."""
