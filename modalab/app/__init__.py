"""The application: the ``modalab`` command line, the stages it runs, project runs, campaigns, the report.

It is the top layer and the only one that sees every stage package (``acquisition``, ``hardware_sim``,
``identification``, ``updating``); nothing below imports it.
"""
