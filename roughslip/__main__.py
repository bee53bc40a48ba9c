"""``python -m roughslip`` runs the command line."""

from roughslip.cli import main

if __name__ == "__main__":
    main()
