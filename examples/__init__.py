"""Systems beyond the book, each a model, a task and its registration, written as a user
would with the public API only (`dynamics.spec`, `envs`). Importing a module registers its
env, so every command takes it as `examples.<module>:<id>`."""
