"""Benchmarks behind ``humv-usd bench``: they may import any tool (they sit above the tools)."""
