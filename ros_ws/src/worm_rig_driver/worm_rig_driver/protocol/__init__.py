"""The rig's serial protocol: ``table`` (the one definition), ``codec`` (COBS, CRC, frames),
``scaling`` (raw ADC codes, counts and duties <-> SI), ``stream_fuzz`` (damaged streams for tests)."""
