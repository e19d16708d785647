"""The live pipeline, Qt-free: a frame source → acquisition thread → processing thread →
consumers (loggers, UDP forwarder, views) through bounded queues. See docs/pipeline.md."""
