"""Training: the loop (:mod:`.trainer`), what assembles a run (:mod:`.builder`) and what a run writes
(:mod:`.outputs`), the ray bank and batches (:mod:`.batch`), the inputs set up on the bank (priors aligned, the SfM
cue and depth term: :mod:`.inputs`), the objective as a table of terms (:mod:`.objective`, their math in
:mod:`.losses`), the optimiser (:mod:`.optim`) and its device-resident update (:mod:`.device_step`), the
densification strategy (:mod:`.strategy`), the policy that drops sets a room does not need (:mod:`.components`) and
a method's own parts (Ref-GS's grid: :mod:`.refgs`)."""
