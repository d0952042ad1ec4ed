"""Benchmark scripts against simple references and real peers, and the screenshot helper."""
