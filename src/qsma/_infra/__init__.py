"""What every layer of qsma may use and none owns: old import paths forwarded
(:mod:`.deprecation`)."""
