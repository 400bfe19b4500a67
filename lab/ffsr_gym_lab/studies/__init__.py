"""The RL study's plan (what a resumed study has left) and the hyperparameter searches with Optuna."""
