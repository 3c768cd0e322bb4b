"""The composition root and commands as library calls: ``connect`` (session), ``toaster run``
(runs) and ``toaster demo`` (demo)."""
