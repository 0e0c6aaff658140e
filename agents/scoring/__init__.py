"""Scoring: the evaluation loop, the main job's report, the diagnosis of a miss, and what the
main job adds about a trained agent."""
