"""Readers for real robot data: CARMEN laser logs (:mod:`envs.logs.carmen`) and 2D pose graphs in
g2o and TORO format (:mod:`envs.logs.g2o`). Both raise one line naming the file, the line number
and what was expected for a malformed line."""
