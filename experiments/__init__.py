"""Research scripts on masp-lite's public API; each asks one question (see ``experiments/README.md``)."""
