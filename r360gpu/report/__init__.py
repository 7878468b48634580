"""Reports: tables in Markdown/LaTeX, pictures, HTML."""
