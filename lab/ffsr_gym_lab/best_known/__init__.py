"""The best known score of every pool task: its stored records, the per-task search, the resumable build of the
shipped file, the checks every record passes before it is assembled, and the screened second pass."""
