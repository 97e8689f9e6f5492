"""USD helpers of HumV-USD: schema registration and the schema/attribute names (``schemas``)."""
