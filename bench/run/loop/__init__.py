"""Configuration and the PDO loop: the canopen master configures both nodes by SDO, enables the drive, steps the
lockstep segments and reads the statuses at the end (Session, composed of a Configurator and a loop driver)."""
