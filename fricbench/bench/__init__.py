"""Benchmark runner, metrics, leaderboard writer and the perf benchmark."""
