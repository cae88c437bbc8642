"""The tracing layer: one traversal of a batch of rays (``driver.traversal`` is its entry point),
how its requests reach a backend (``issue``), their record (``record``) and the instance stepper
(``stepper``); docs/architecture.md."""
