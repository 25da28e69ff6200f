"""The scripts behind damjax's verification pages and figures: ``python -m verification``
lists each with the page it feeds; ``python -m verification.NAME`` runs one."""
