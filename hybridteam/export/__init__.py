"""Views of models and runs: state diagrams, timelines, trajectories, sequence charts."""
