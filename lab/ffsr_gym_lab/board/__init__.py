"""The leaderboard's maintenance: entries' storage and recomputation, the tables and how finely they rank, the
scores over best known scores, the aggregates across tiers, the Pareto fronts and the figures."""
