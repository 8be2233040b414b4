"""Publishing: leaderboards (entries, pages, plots) and renders of clips and samples."""
