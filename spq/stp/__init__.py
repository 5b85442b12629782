"""What is specific to STP-BV: its topology (``topology``) and its construction from points
(``construction``)."""
