"""Studies: many runs of one scenario — sweeps, minimum-headway search, VC vs moving block, paper reproductions."""
