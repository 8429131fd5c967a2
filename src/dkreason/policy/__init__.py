"""The matching policy as a program: rule files read (`syntax`, and `tables` for the facts of
the tables they name), their constants written as names resolved (`resolve`), and the static
checks every policy passes before a rule of it reaches the engine (`check`); `load` reads a
policy's files as one program."""
