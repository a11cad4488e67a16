"""``notchfit review``: look at every detection of a detect run and correct it in the browser.

=====================  ========================================================
module                 what
=====================  ========================================================
:mod:`.pixels`         image pixels <-> plane millimetres, as the detect run mapped them
:mod:`.measure`        the live free-θ fit of one sample, the angles by hand
:mod:`.session`        the corrections model: detections + review.csv, edits, undo, conflicts
:mod:`.images`         the image pyramid and its tiles, the thumbnails
:mod:`.server`         the local HTTP server (127.0.0.1 only) and its JSON API
``static/``            the page: plain HTML, JavaScript and CSS (no build step, no internet)
=====================  ========================================================

docs/review.md describes the page and its choices.
"""
