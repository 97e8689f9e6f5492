"""pipeline tool."""
