"""atmosphere tool."""
