"""damjax benchmark suite: ``python -m benchmarks [CASE ...]`` prints JSON lines."""
