"""The human model shared by the avatar and clothing tools: MakeHuman CC0 base mesh and macro
targets (``body``, ``macro``, ``basemesh``), the rig and skinning (``skeleton``, ``usdskel``),
body regions and JOS-3 segments (``labels``), motion (``gait``, ``motion``, ``bvh``,
``contact``) and carried props (``carry``). No layer is written here.
"""
