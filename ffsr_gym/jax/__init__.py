"""The v2 closed loop as pure JAX functions (``pip install "ffsr-gym[jax]"``), for ``jit``, ``vmap``, ``lax.scan``
and gradients through the loop. Its modules turn on JAX's 64-bit floats when imported (``jax_enable_x64``): the
loop is verified against the float64 kernel."""
