"""``python -m toaster`` runs the command line."""

from toaster.cli import main

main()
