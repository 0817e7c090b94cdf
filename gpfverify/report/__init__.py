"""Report primitives: the document blocks of a page (:mod:`.document`), Markdown and HTML rendering
(:mod:`.render`), figures (:mod:`.figures`), the files a section is rendered from (:mod:`.inputs`),
the pages of ``gpfverify check`` and ``gpfverify audit`` (:mod:`.equivalence`) and of the proofs
(:mod:`.proofs`). Nothing here knows a paper: the papers' sections (:mod:`gpfverify.papers`) build
on these, and :mod:`gpfverify.full_report` assembles them into the whole report. This package reads
and renders; it never runs an experiment and imports nothing from :mod:`gpfverify.experiments`.
"""
