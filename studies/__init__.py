"""The top floor: studies of machines, reports, the `precrel` command line, the paper's case
study and benchmarks, in rooms by who they serve (see docs/layout.md)."""
