"""The paper's tables, its case study (`python -m studies.reproduce_paper`), its report and the
paper's studies."""
