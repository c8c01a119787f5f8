"""Training of the OutCast networks: configs, data pipeline, losses, the trainer and the CLI."""
