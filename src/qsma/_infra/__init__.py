"""What every layer of qsma may use and none owns: old import paths forwarded
(:mod:`.deprecation`), files written atomically (:mod:`.files`), dense symmetric
matrices (:mod:`.dense`), BLAS and solve threads (:mod:`.threads`), the memory and CPU
of the process (:mod:`.resources`), work on a forked second process (:mod:`.forked`),
objects sent to Dask workers (:mod:`.shipping`)."""
