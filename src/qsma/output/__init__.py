"""What a run leaves on disk: the result files (:mod:`.files`: results.json,
results.csv, VTU fields), the result folders every command writes into
(:mod:`.folders`: lock, staging, manifest, atomic swap), the figures (:mod:`.plots`,
matplotlib kept here), the figures drawn by a forked process beside the analysis
(:mod:`.plotworker`) and report.html (:mod:`.report`).

Nothing is imported here: matplotlib and the writers load only when a module of this
package is imported, so a command that writes no figure never pays for them."""
