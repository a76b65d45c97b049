; Hand-written for feedloop's tests (no third-party content): the styles that PrusaSlicer,
; Cura, Slic3r and Marlin hosts emit, one per line. Every line must parse without error.
;FLAVOR:Marlin
;Generated with a Cura-like header
M140 S60
M105
M190 S60
M104 S200
M105
M109 S200
M82 ;absolute extrusion mode
G28 ;Home
G1 Z15.0 F6000 ;Move the platform down 15mm
G92 E0
G1 F200 E3
G92 E0
G0 F9000 X110.500 Y95.200 Z0.300
G1 F1500 E-6.5
G1 X111.5 Y96.2 E0.03325
M204 S500
M205 X10 Y10
M106 S255
M107
M220 S100
M221 S100
; Slic3r style
G21 ; set units to millimeters
G90 ; use absolute coordinates
M83 ; use relative distances for extrusion
G1 Z0.350 F7800.000
G1 X90.210 Y89.412 E0.04317 F1800.000
G1 E-2.00000 F2400.00000
; Marlin host style: compact words, lower case, parentheses comments
g1 x10 y20 f3000
G1X10Y20E1.5F1200
G1 X10 (inline comment) Y20
G4 P100
G4 S1
G2 X10 Y10 I5 J0 F1200
G3 X0 Y0 R5
G10
G11
G20
G21
G91
G90
M84 X Y E
M84 S120
M110 N0
M114
M115
M117 Printing... 50% done
M201 X3000 Y3000 Z100 E5000
M203 X300 Y300 Z12 E120
M204 P3000 R3000 T3000
M205 X8.00 Y8.00 Z0.40 E4.50 J0.013
M205 S0 T0 B20000
M73 P50 R10
M400
T0
M84
