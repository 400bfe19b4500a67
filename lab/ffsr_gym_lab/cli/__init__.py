"""The lab's sub-commands, loaded by ``ffsr-gym`` from the ``ffsr_gym.commands`` entry point."""
