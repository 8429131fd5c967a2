"""The matching policy as a program: rule files read (`syntax`), their constants written as
names resolved (`names`), their tables of facts read (`tables`), and the static checks every
policy passes before a rule of it reaches the engine (`check`)."""
