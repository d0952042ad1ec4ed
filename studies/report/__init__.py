"""Results into reports: the writer (markdown and self-contained HTML), the sections, markdown
tables and the figures."""
