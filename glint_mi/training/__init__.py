"""Training: the loop (:mod:`.trainer`), the ray bank and batches (:mod:`.batch`), the inputs set up on the bank (priors
aligned, the SfM cue and depth term: :mod:`.inputs`), the objective (:mod:`.losses`,
:mod:`.depth_rules`), the optimiser (:mod:`.optim`) and its device-resident update (:mod:`.device_step`), the
densification strategy (:mod:`.strategy`) and the policy that drops sets a room does not need (:mod:`.components`)."""
