"""Benchmarks: plain scripts that measure and print; `make bench` runs them all."""
