"""Files in, files out: read and write settings, reporting, batches, sequences, shards, streaming, clusters and
farms, and the one dispatcher :func:`pyramid_cli.run.pipeline.process`."""
