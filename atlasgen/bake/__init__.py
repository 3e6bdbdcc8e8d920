"""From materials to an atlas: slices, the cache, mips, the DDS, the manifest and the include."""
