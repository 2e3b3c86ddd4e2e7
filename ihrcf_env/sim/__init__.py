"""PyBullet simulation layer: one explicit physics client per world."""
