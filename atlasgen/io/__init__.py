"""Files atlasgen reads and writes: DDS, the atlas pair, atomic writes, depfiles, report JSON,
PNG and EXR images."""
