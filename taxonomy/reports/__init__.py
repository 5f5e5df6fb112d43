"""Reports of the results: tables and HTML reports (:mod:`.report`) and figures (:mod:`.plots`).

Imported by their own names, since they build on the learning modules.
"""
