"""Reports: tables (Markdown, CSV, LaTeX), figures and plotting helpers, house drawings and
statistics, all read from a run through the run store."""
