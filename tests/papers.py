"""The three papers' scenarios as the frame-set and CAN FD tests run them (tests/host/test_frame_sets.py,
tests/host/test_can_fd.py): You 2019's step, Yao 2020's identification and Zhao 2022's stability point, with the
plant's sensor models on (a quantizing ADC and You 2019's 2500-line encoder: the compact frame's codes then carry
the readings exactly)."""

PAPERS = [
    "scenarios/you2019_step.toml",  # You 2019, the deadbeat step
    "scenarios/yao2020_identification.toml",  # Yao 2020, the R/L identification
    "scenarios/zhao2022_stability.toml",  # Zhao 2022, a stability point
]
SENSORS = ["drive.adc_lsb_A=0.005", "drive.encoder_lines=2500"]  # quantizing ADC, You 2019's 2500-line encoder
