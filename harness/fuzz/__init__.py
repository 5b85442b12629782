"""`spq fuzz`: a seeded, resumable campaign over adversarial shape and pose families (families), every
query judged against independent support functions, two or more peers and, on every disagreement and
a random sample, the exact reference or the depth oracle (oracle, judge); every wrong or failed spq
case shrunk to a small reproducer (shrink) saved for the test suite; the campaign's state checkpointed
(campaign)."""
