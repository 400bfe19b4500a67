"""Task pools: the resumable build of a version's pools, their docs tables, and the frozen reference's writing."""
